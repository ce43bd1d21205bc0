"""Tick statuses shared by behavior-tree nodes, skill requests and FSM replies."""
from enum import IntEnum

__all__ = ["Status", "RUNNING", "SUCCESS", "FAILURE"]


class Status(IntEnum):
    """The three statuses of a tick. Small ints so the hot path compares ints."""

    RUNNING = 0
    SUCCESS = 1
    FAILURE = 2

    @classmethod
    def parse(cls, text: "str | Status") -> "Status":
        """Accept a Status or its name in any case (``"success"``)."""
        if isinstance(text, Status):
            return text
        try:
            return cls[str(text).upper()]
        except KeyError:
            raise ValueError(f"unknown status {text!r} (expected success, failure or running)") from None


RUNNING, SUCCESS, FAILURE = Status.RUNNING, Status.SUCCESS, Status.FAILURE
