"""What a shell has told its command process that holds until it says otherwise: the design in
force (with `speed_profile: cam`, the cam planned here in the shell first: a plan holds the
interpreter for up to tens of ms, and the command process's SYNC loop must not wait for it) and
each row's section. A restarted command process is told them again (`tell_again`).
"""
from __future__ import annotations

from collections.abc import Callable
import logging
import threading
from typing import Any

from planter_ros.cam import CamError, CamProfile
from planter_ros.control.cam_law import plan_for_design, profile_to_data, warm_up
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.design import Design

from .channel import Channel
from .state import Log

__all__ = ['Orders']

Send = Callable[..., bool]          # (kind, payload) -> sent


class Orders:
    """The design and the sections a shell gave its command process (see the module doc)."""

    def __init__(self, law: PhaseLockConfig, rows: list[str], log: Log, send: Send) -> None:
        """`rows`: the names of the rows on the bus (their sections start on); `send`: the
        shell's way to its command process (kind, payload)."""
        self.law = law
        self.log = log
        self.send = send
        self.design: str | None = None
        # the last design as sent (kind, payload); with a cam, once planned
        self._message: tuple[str, Any] | None = None
        self.cam = law.speed_profile == 'cam'
        self._profile: CamProfile | None = None     # the cam profile sent last
        if self.cam:            # the first plan imports and sets up the LP solver (~0.4 s)
            threading.Thread(target=warm_up, daemon=True, name='cam-warm-up').start()
        self.sections: dict[str, bool] = {name: True for name in rows}

    def set_design(self, design: Design, text: str, now: float) -> bool:
        """A design for the command process; False when it is the one sent last."""
        if text == self.design:
            return False
        self.design = text
        if self.cam:
            self._message = None
            threading.Thread(target=self._plan_cam, args=(design, text, now), daemon=True,
                             name='cam-plan').start()
            return True
        self._message = ('design', text)
        self.send('design', text)
        return True

    def _plan_cam(self, design: Design, text: str, arrived: float) -> None:
        """Plan the cam and the change from the one sent last (planter_ros.control.cam_law);
        one over the drive's limits is refused here, before it reaches the command process."""
        previous = self._profile
        try:
            profile, why = plan_for_design(design, self.law.cam_rule, previous)
            data = None if profile is None else profile_to_data(profile, previous)
        except CamError as exc:
            self.log(logging.ERROR, f'design refused, the rows keep theirs: {exc}')
            return
        if text != self.design:             # a newer design came meanwhile
            return
        self._profile = profile
        message = ('design_cam', [text, data, why, arrived])
        self._message = message
        self.send(*message)

    def tell_again(self, channel: Channel) -> None:
        """A restarted command process: the design and the sections switched off, again (a
        cam not planned yet follows once it is)."""
        if self.design is not None:
            if self._message is not None:
                channel.send(*self._message)
            elif not self.cam:
                channel.send('design', self.design)
        for name, on in self.sections.items():
            if not on:
                channel.send('section', [0, name, False])
