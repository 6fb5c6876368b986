"""The project's own error types.

Every edge of the system (files, messages, CLI arguments) raises one of these with a message that names
what was wrong, so a service can log it and go on instead of crashing on a library's exception.
"""


class HrcError(Exception):
    """Base class of every error the project raises on purpose."""


class ConfigError(HrcError):
    """A configuration or data file is missing, malformed or out of range; the message names the field."""


class MessageError(HrcError):
    """A wire message could not be decoded or failed validation; the message names the field. reason: how a
    refusal is counted where refusals are counted by kind (the ROS 2 bridge: "invalid", "stale", "partly seen")."""

    def __init__(self, text: str = "", reason: str = "invalid") -> None:
        super().__init__(text)
        self.reason = reason


class KeyError_(HrcError):
    """A Zenoh key or cell prefix is malformed."""
