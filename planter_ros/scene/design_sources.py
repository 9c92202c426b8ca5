"""Who set the design: the publishing node of every design the sync node and the monitor accept.

The design topic is latched and anyone on the graph may publish it; a change from a node that
is not the machine's design node (a second design_node started with another scene, a test
tool) moves the whole machine to another spacing. So each accepted design is attributed to its
publisher, logged and counted. Jazzy's rclpy does not hand a Python callback the publisher's
GID, so the attribution comes from the graph (the topic's publishers, by node name and endpoint
GID) at the moment the message is taken: the only publisher, else the one publisher that
appeared since the last look (a new publisher of a latched topic delivers its sample as soon
as it is matched), else every candidate is named ("one of ..."). A change counts as foreign
when it surely came from none of the publishers of the first design. Pure: no ROS import.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

from planter_ros.diagnostics import DESIGN, OK, STALE, WARN, Report

__all__ = ['Attribution', 'DesignSources', 'Endpoint', 'gid_text']


@dataclass(frozen=True)
class Endpoint:
    """One publisher of the design: its node's full name and its endpoint GID (hex)."""

    node: str
    gid: str

    @property
    def named(self) -> bool:
        """False while the graph knows the endpoint but not yet its node (rclpy then names it
        '_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_')."""
        return UNKNOWN not in self.node


UNKNOWN = '_UNKNOWN_'


def gid_text(gid_bytes: Iterable[int]) -> str:
    """An endpoint GID as ROS prints it: bytes as two hex digits joined by dots."""
    return '.'.join(f'{b:02x}' for b in gid_bytes)


@dataclass(frozen=True)
class Attribution:
    """Where one accepted design came from."""

    candidates: tuple        # Endpoint(s) it can have come from
    first: bool              # the first design this node accepted
    foreign: bool            # surely not from a publisher of the first design

    @property
    def named(self) -> bool:
        return all(e.named for e in self.candidates)

    @property
    def text(self) -> str:
        nodes = sorted({e.node for e in self.candidates})
        if not nodes:
            return 'a publisher no longer on the graph'
        if len(nodes) == 1 and len(self.candidates) == 1:
            return f'{nodes[0]} (publisher {self.candidates[0].gid})'
        if len(nodes) == 1:
            return f'{nodes[0]} (one of {len(self.candidates)} publishers of that name)'
        return 'one of ' + ', '.join(nodes)


class DesignSources:
    """Attributes, counts and reports the designs one node accepts."""

    def __init__(self) -> None:
        self.known: dict[str, str] = {}   # gid -> node name, every publisher seen on the topic
        self.first: Attribution | None = None         # of the first design
        self.changes = 0             # designs accepted after the first
        self.foreign_changes = 0
        self.last_change: Attribution | None = None   # of the latest change

    def accepted(self, endpoints: Iterable[Endpoint]) -> Attribution:
        """A design was accepted; `endpoints` are the topic's publishers now. Returns its
        Attribution (and counts it)."""
        now = tuple(endpoints)
        new = tuple(e for e in now if e.gid not in self.known)
        self._learn(now)
        candidates: tuple[Endpoint, ...]
        if len(now) == 1:
            candidates = now
        elif len(new) == 1:
            candidates = new
        else:
            candidates = now
        if self.first is None:
            first = self.first = Attribution(candidates, True, False)
            return first
        original = {e.gid for e in self.first.candidates}
        foreign = not any(e.gid in original for e in candidates)
        self.last_change = Attribution(candidates, False, foreign)
        self.changes += 1
        self.foreign_changes += foreign
        return self.last_change

    def refresh(self, endpoints: Iterable[Endpoint]) -> None:
        """Learn the node names the graph did not know yet when a design arrived (a latched
        sample can come before its node's discovery) and name the attributions with them."""
        self._learn(endpoints)
        self.first = self.named(self.first)
        self.last_change = self.named(self.last_change)

    def named(self, attribution: Attribution | None) -> Attribution | None:
        """`attribution` with every candidate named as far as the graph has told us."""
        if attribution is None:
            return None
        return replace(attribution, candidates=tuple(
            Endpoint(self.known.get(e.gid, e.node), e.gid) for e in attribution.candidates))

    def _learn(self, endpoints: Iterable[Endpoint]) -> None:
        for e in endpoints:
            if e.named or e.gid not in self.known:
                self.known[e.gid] = e.node

    def values(self) -> list[tuple[str, str | int]]:
        """Key/value pairs for /diagnostics."""
        out: list[tuple[str, str | int]] = [('design from', self.first.text if self.first else ''),
               ('design changes', self.changes),
               ('design changes by other nodes', self.foreign_changes),
               ('design publishers seen', ', '.join(sorted(set(self.known.values()))))]
        if self.last_change is not None:
            out.append(('last design change from', self.last_change.text))
        return out

    def report(self) -> Report:
        """The node's 'design' status: WARN once another node changed the design."""
        values = tuple(self.values())
        if self.first is None:
            return Report(DESIGN, STALE, 'waiting for design', values)
        last = self.last_change      # set with every change counted
        if last is not None and self.foreign_changes:
            return Report(DESIGN, WARN, f'{self.foreign_changes} design change(s) by another '
                          f'node, the latest from {last.text}', values)
        if last is not None and self.changes:
            return Report(DESIGN, OK, f'{self.changes} design change(s), the latest from '
                          f'{last.text}', values)
        return Report(DESIGN, OK, f'from {self.first.text}', values)
