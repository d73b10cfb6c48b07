"""The one error type for bad input: it names the field and says how to fix it."""


class InputError(ValueError):
    """Bad input (config, scheme or data file). ``field`` names where; ``message`` says why."""

    def __init__(self, field: str, message: str):
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")
