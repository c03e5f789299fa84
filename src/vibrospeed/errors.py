"""Exception classes. Every message is one line that names the file, row or channel at fault.

The CLI turns any :class:`VibrospeedError` into that line on stderr and exit status 2.
"""


class VibrospeedError(Exception):
    """Base class of every error vibrospeed raises on purpose."""


class ParameterError(VibrospeedError, ValueError):
    """A parameter is out of range or inconsistent (e.g. Nyquist violated)."""


class InputError(VibrospeedError, ValueError):
    """Data that cannot be used: missing channel, all-NaN channel, time going backwards..."""


class ReaderError(InputError):
    """A file that cannot be read: missing, empty, malformed, unknown format.

    Parameters
    ----------
    path : file at fault
    message : what is wrong
    row : 1-based line number in the file (header = line 1), if known
    column : column or channel name, if known
    """

    def __init__(self, path, message: str, *, row: int | None = None, column: str | None = None):
        where = str(path)
        if row is not None:
            where += f", line {row}"
        if column is not None:
            where += f", column '{column}'"
        super().__init__(f"{where}: {message}")
        self.path = path
        self.row = row
        self.column = column
