"""The simulated AKD: a drive model with PNU and SDO servers speaking the real wire formats."""
