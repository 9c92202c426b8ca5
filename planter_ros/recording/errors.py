"""The errors of reading, replaying and writing recordings: one family, one class per remedy.

Every error is a RecordingError with a one-line message that names the file (or topic, or
message) and what is wrong with it; `planter` prints it and exits with code 2. Catch
RecordingError for "this recording cannot be used"; catch a subclass only to act on that case:

* BagUnreadableError: nothing in it can be read (no such bag, not MCAP, no valid MCAP record
  at all). Check the path.
* BagDamagedError: part of a file is damaged (a record, a chunk's CRC, the summary or an index
  that disagrees with its records). The readers catch it themselves and read every intact part
  (a damaged part is a warning with the time range it held); it reaches only a caller of the
  low-level readers (recording.indexed, recovery.record_at).
* TopicMissingError: the bag is readable but lacks a topic replay needs (the message lists the
  topics it has). Record those topics, or pick the right bag.
* DecodeError: one message's bytes are not the type it was recorded as (recording.cdr).
* ReplayError: the bag was read, yet there is nothing to predict with: no usable design in it
  (give the run's scene) or the scene given has none.
* BagWriteError: a bag cannot be written as asked: the path exists (bags are never
  overwritten) or cannot be created, a split bag given a `.mcap` path, a recorder setting out of
  range, a message type without a definition to embed, a write after close.
"""

from __future__ import annotations

from planter_ros.errors import PlanterError


class RecordingError(PlanterError):
    """A recording that cannot be read, replayed or written as asked (one line)."""


class BagUnreadableError(RecordingError):
    """Nothing in the bag can be read: it does not exist, is not MCAP or holds no valid record."""


class BagDamagedError(RecordingError):
    """Part of a file is damaged; `reason` says what in a few words, `at` is the byte offset of
    the damaged record when one is known (the message then starts `record at byte <at>`)."""

    def __init__(self, reason: str, at: int | None = None) -> None:
        super().__init__(reason if at is None else f'record at byte {at}: {reason}')
        self.reason = reason
        self.at = at


class TopicMissingError(RecordingError):
    """The bag lacks a topic the task needs (the message names the topics it has)."""


class DecodeError(RecordingError):
    """One message cannot be decoded as the type it was recorded as."""


class ReplayError(RecordingError):
    """The bag was read, yet replay has no usable design to predict with."""


class BagWriteError(RecordingError):
    """A bag that cannot be written as asked (the path or value, and why)."""


__all__ = ['BagDamagedError', 'BagUnreadableError', 'BagWriteError', 'DecodeError',
           'RecordingError', 'ReplayError', 'TopicMissingError']
