"""Pure wire codecs: bytes in, objects out, no I/O and no akdctl imports outside this package."""
