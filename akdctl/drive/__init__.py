"""Drive profiles and operations: the meaning of parameters, objects, control and status words."""
