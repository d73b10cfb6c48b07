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


EXIT_REFUSED = 2
"""Exit status of a command or a workflow job refused for bad input or a failed write (README,
"Exit statuses")."""


def error_line(exc: BaseException) -> str | None:
    """The one-line message (no traceback) of an error the user can fix -- bad input (the field and
    why) or an output that could not be written (the path and why: a full disk, no permission) --
    or None for any other error (a bug: its traceback is wanted). The one translator of the
    command line (:func:`platcal.cli.main`) and the workflow's jobs (:func:`platcal.log.job_logger`)."""
    if isinstance(exc, InputError):
        return f"{exc.field}: {exc.message}"
    if isinstance(exc, OSError):
        done = ("; nothing was written under that name (the files already there are untouched)"
                if isinstance(exc, WriteError) else "")
        return (f"{exc.filename or '(no path)'}: {exc.strerror or exc}{done}; "
                "free space or fix the permissions and run again")
    return None
