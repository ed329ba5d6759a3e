"""`mna` subcommands of the demo stage (not wired yet)."""


def register(subparsers) -> None:
    """Add this group's subcommands to the `mna` parser."""
