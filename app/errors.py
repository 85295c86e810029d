"""The one error hierarchy of c2n.

Library errors (tomllib, cantools, python-can, OS) are translated into these at the edge, with
the file and the fix in the message, so the CLI can print one line and exit 1.
"""


class C2nError(Exception):
    """A user-facing error: its message is one line naming the file or field and the fix."""


class ConfigError(C2nError):
    """The vehicle config file is missing, malformed or inconsistent with its DBCs."""


class DbcError(C2nError):
    """A DBC file is missing or does not parse."""


class LogFileError(C2nError):
    """A CAN log file is missing, of an unknown format, or unreadable."""


class BusError(C2nError):
    """A CAN interface could not be opened or failed."""


class NoResultError(C2nError):
    """The input was read but cannot give a C2n (e.g. a required role had no frames)."""
