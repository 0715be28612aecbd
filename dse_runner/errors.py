"""The one exception type users catch: every message names its culprit."""


class DseError(Exception):
    """A problem with the user's input or model, with a message meant for them."""
