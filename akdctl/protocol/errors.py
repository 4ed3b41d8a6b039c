"""The one error type every codec raises on malformed or impossible input.

Codecs never let ``struct.error``, ``IndexError`` or ``ValueError`` escape:
callers (transports, servers, fuzz tests) rely on catching exactly this type.
"""


class CodecError(ValueError):
    """Bytes that do not decode, or an object that cannot be encoded."""
