"""The error types the command line turns into one-line messages: bad input (it names the field
and says how to fix it) and an output that could not be written (it names the path)."""


class InputError(ValueError):
    """Bad input (config, scheme or data file). ``field`` names where; ``message`` says why."""

    def __init__(self, field: str, message: str):
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")


class WriteError(OSError):
    """An output that could not be written (a full disk, no permission, a read-only file system),
    raised by the atomic writers of :mod:`platcal.io` with the FINAL path as ``filename`` (not the
    temporary): every temporary of the write is removed, so nothing half-written is left and the
    files already under the final names are untouched."""
