"""Errors the CLI turns into one clear line and exit code 2 (never a traceback)."""


class MnaError(ValueError):
    """Bad input or an impossible request, with a message meant for the user."""


class InputError(MnaError):
    """The input file or its contents cannot be used."""
