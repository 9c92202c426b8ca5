"""A design for every row of the command engine: the cam planned first (`speed_profile: cam`,
in a worker thread: never on the SYNC loop), the joint angle placed at the design's bottom angle
(rows with a machine file's phase offset), where the mechanism plants found in a worker thread.

Owns the design in force (`design_key`, `mechanism`) and the one being planned.
"""
from __future__ import annotations

from collections.abc import Sequence
import logging
import math
import threading
import time
from typing import Any

import numpy as np

from planter_ros.cam import CamError
from planter_ros.control.cam_law import plan_for_design
from planter_ros.control.phase_lock import planting_angles
from planter_ros.design import Design

from .state import EngineState

__all__ = ['DesignChange', 'bottom_angle']


class DesignChange:
    """The design the rows run and the changes to it (see the module doc)."""

    def __init__(self, state: EngineState) -> None:
        self.state = state
        self.log = state.log
        self.design_key: tuple | None = None    # (spacing, plants per revolution, text)
        self._planning: str | None = None       # the design whose cam is being planned
        self.mechanism: str | None = None

    def set_design(self, design: Design, text: str, now: float,
                   planned: tuple[Any, str] | None = None,
                   arrived: float | None = None) -> bool:
        """A design for every row (at its next planting instant); False when it is the one in
        force already. Where the mechanism plants is found in a worker thread. With
        `speed_profile: cam` the cam is planned first, in a worker thread too (it takes up to
        tens of ms: not on the SYNC loop), and the design applies once it is; `planned`:
        (profile or None, why not) when the caller planned it (the command process's shell),
        `arrived` when the design reached it (monotonic s)."""
        if planned is not None:
            with self.state.lock:
                if self.design_key is not None and text == self.design_key[2]:
                    return False
                self._planning = None
            return self._apply_design(design, text, now, *planned, since=arrived)
        with self.state.lock:
            if self.design_key is not None and text == self.design_key[2]:
                return False
            if self.state.law.config.speed_profile == 'cam':
                if self._planning == text:
                    return False
                self._planning = text
                threading.Thread(target=self._plan_cam, args=(design, text, now), daemon=True,
                                 name='cam-plan').start()
                return True
        return self._apply_design(design, text, now, None)

    def _plan_cam(self, design: Design, text: str, now: float) -> None:
        """Plan the design's cam and the change to it (worker thread), then apply the design
        with it; a plan or change over the drive's limits is refused (logged, not applied)."""
        previous = next((unit.law.cam for unit in self.state.units if unit.law.cam is not None),
                        None)
        try:
            profile, why = plan_for_design(design, self.state.law.config.cam_rule, previous)
            with self.state.lock:
                if self._planning != text:       # a newer design arrived meanwhile
                    return
                self._planning = None
                self._apply_design(design, text, time.monotonic(), profile, why, since=now)
        except CamError as exc:
            with self.state.lock:
                if self._planning == text:
                    self._planning = None
            self.log(logging.ERROR, f'design refused, the rows keep theirs: {exc}')

    def _apply_design(self, design: Design, text: str, now: float, cam: Any,
                      why: str = '', since: float | None = None) -> bool:
        with self.state.lock:
            self._place_bottom(bottom_angle(design))
            spacing, n = design.plant_spacing, design.plants_per_revolution
            joints = [unit.row.joint(design.mechanism) for unit in self.state.units]
            cams = None
            if self.state.law.config.speed_profile == 'cam':
                cams = []
                for unit in self.state.units:
                    fallback = why
                    if not fallback and unit.drive is not None and not unit.csp:
                        fallback = ('the drive runs profile velocity (no CSP): the cam falls '
                                    'back to the mean speed (constant profile)')
                    cams.append(None if fallback else cam)
                    if fallback and fallback != unit.law.cam_fallback:
                        self.log(logging.WARNING, fallback if self.state.implicit
                                 else f'row {unit.label}: {fallback}')
                    unit.law.cam_fallback = fallback
            self.state.machine.set_design(spacing, n, now, cams=cams, since=since)
            key = (spacing, n, text)
            self.design_key = key
            self.mechanism = design.mechanism
            for unit, joint in zip(self.state.units, joints):
                unit.joint = joint
        threading.Thread(target=self._find_planting_angles, args=(design, key), daemon=True,
                         name='planting-angles').start()
        return True

    def _place_bottom(self, bottom: float) -> None:
        """Rows with a phase offset (a machine file): the joint angle = the drive's - the
        phase offset + the design's bottom angle `bottom` (where its tip is lowest), so the law
        and the monitor plant where the design plants. Every angle the row holds follows a
        change (lock held; before the design anchors the grid)."""
        for unit in self.state.units:
            if unit.phase_offset is None:
                continue
            shift = bottom - unit.phase_offset
            delta = shift - unit.angle_shift
            if delta == 0.0:
                continue
            unit.angle_shift = shift
            unit.law.shift_angle(delta)
            if unit.target is not None:
                unit.target += delta
            if unit.status is not None:
                unit.status = unit.joint_status(unit.status)

    def _find_planting_angles(self, design: Design, key: tuple) -> None:
        planting = planting_angles(design)
        with self.state.lock:
            if key == self.design_key:
                self.state.machine.set_planting(planting)

    def configure(self, law_values: Sequence[Any]) -> None:
        with self.state.lock:
            self.state.machine.configure(*law_values)


def bottom_angle(design: Design) -> float:
    """The shaft angle (rad) at which the design's tip is lowest: the five-bar's π (θ = 0 at
    the top), a tip path's lowest sample."""
    path = getattr(design, 'tip_path', None)
    if path is None:
        return math.pi
    return float(np.asarray(path.angle)[int(np.argmin(np.asarray(path.y)))])
