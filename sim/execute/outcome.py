"""A physics run's outcome: :class:`SimReport`, its verdict line and its JSON, and the end-of-run matching."""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..words import plural, reached_phrase, run_notes
from .contacts import Contact
from .drive_timing import timing_notes
from .events import ContactEvent, group_events
from .realism import Disturbance
from .recovery import Replan

__all__ = ["SimReport", "assemble", "filled", "reached"]

_LIST_MAX = 1000  # contacts and disturbances listed in full by SimReport.to_dict


def _finite(v: float):
    v = float(v)
    return v if math.isfinite(v) else None



@dataclass(frozen=True, eq=False)
class SimReport:
    """The outcome of one physics run.

    contacts: every touching episode, both witnesses, in time order.
    min_clearance: smallest gap seen by the monitor [units]: between two
        disc boundaries, or between a disc and an obstacle or wall
        (negative means overlap).
    min_clearance_time: when it occurred [s].
    max_tracking_error: the largest ``|x - x_ref|`` over working robots and
        all samples, settling included [units].
    reached: after settling, every working robot is within ``tolerance`` of
        a distinct target (minimum-cost matching of robots to targets).
    final_error: the largest matched robot-target distance at the end [units].
    sim_time_s: simulated time [s]; wall_time_s: wall-clock time of the run [s].
    times: ``(T,)`` sample times, one per control step, from 0.
    positions: ``(T, m, 2)`` body positions at those times.
    min_clearance_kind, min_clearance_pair: what attained ``min_clearance``
        (two robots; or a robot and an obstacle index, ``-1`` for the wall).
    step_time_s: wall-clock time spent inside ``space.step`` [s].
    min_gap: ``(T,)`` smallest gap of each sample over all robot pairs,
        obstacles and walls [units], exact up to one robot diameter
        (larger gaps are recorded as ``2 * radius``).
    tracking_error: ``(T, m)`` distance of each robot from its reference
        [units]; NaN for a failed robot.  The reference is the plan, the
        stop profile while braking for a replan, then the new plan.
    max_tracking_error_time, max_tracking_error_robot: where the largest
        tracking error was [s], robot index.
    reached_robots: ``(m,)`` whether each robot ended within ``tolerance``
        of its matched target (``False`` for a failed robot).
    masses: ``(m,)`` the bodies' real masses.
    failed: the failed robots, in the order they failed.
    disturbances: every impulse, push and failure as applied.
    replans: every replan (:class:`sim.execute.recovery.Replan`).
    stopped: why the run ended early (a replan found no way on), or ``""``.
    targets_filled: how many of the problem's targets have a robot (working
        or failed) within ``tolerance`` at the end (matching).
    phase_margin_deg: the controller's phase margin with its delays
        (:func:`sim.execute.realism.phase_margin`; latency plus half the hold);
        at or below zero the loop is unstable and the verdict says so.
    accept: the rule of :attr:`ok` (``sim.accept``): ``"targets"``, every
        target holds a working robot; ``"working"``, every working robot is
        on a distinct target or its parking place.
    targets_total, targets_working: the problem's targets, and how many of
        them hold a working robot at the end (``-1``: not known).
    budget_exhausted_at: when a tracking-error trigger first found the
        replan budget (``sim.recovery.max_replans``) used up [s], or None.
    on_budget: ``sim.recovery.on_budget``; with ``"fail"`` an exhausted
        budget fails the run.
    headings: ``(T, m)`` each robot's heading at each sample [rad, from +x,
        counter-clockwise], or ``None`` when the drive has none (holonomic
        and velocity robots).
    drive: the drive model (:mod:`sim.execute.drive`).
    drive_timing: whether the drive can keep the plan's timing
        (:func:`sim.execute.drive_timing.drive_timing`), ``None`` for holonomic robots.
    speed_warnings: physics steps in which a body moved too far for pymunk to
        see every contact even in pieces (:class:`sim.execute.contacts.SpeedGuard`).
    """

    contacts: tuple[Contact, ...]
    min_clearance: float
    min_clearance_time: float
    max_tracking_error: float
    reached: bool
    final_error: float
    sim_time_s: float
    wall_time_s: float
    times: np.ndarray
    positions: np.ndarray
    min_clearance_kind: str = ""
    min_clearance_pair: tuple[int, int] = (-1, -1)
    step_time_s: float = 0.0
    min_gap: np.ndarray | None = None
    tracking_error: np.ndarray | None = None
    max_tracking_error_time: float = float("nan")
    max_tracking_error_robot: int = -1
    reached_robots: np.ndarray | None = None
    masses: np.ndarray | None = None
    failed: tuple[int, ...] = ()
    disturbances: tuple[Disturbance, ...] = ()
    replans: tuple[Replan, ...] = ()
    stopped: str = ""
    targets_filled: int = -1
    phase_margin_deg: float = float("nan")
    accept: str = "targets"
    targets_total: int = -1
    targets_working: int = -1
    budget_exhausted_at: float | None = None
    on_budget: str = "fail"
    headings: np.ndarray | None = None
    drive: str = "holonomic"
    drive_timing: dict | None = None
    speed_warnings: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """No contact by either witness, no early stop, no exhausted replan budget (unless
        ``on_budget`` is ``"continue"``), every working robot on a distinct target and, with
        ``accept == "targets"``, every target holding a working robot."""
        if self.contacts or self.stopped or not self.reached or self.budget_failed:
            return False
        return self.accept != "targets" or self.targets_working >= self.targets_total

    @property
    def budget_failed(self) -> bool:
        """The replan budget ran out and ``on_budget`` says that fails the run."""
        return self.budget_exhausted_at is not None and self.on_budget != "continue"

    @property
    def parked(self) -> int:
        """Working robots that end on a parking place (failed robots block their targets)."""
        return len(getattr(self.replans[-1], "parked", ())) if self.replans else 0

    @property
    def first_contact(self) -> Contact | None:
        return self.contacts[0] if self.contacts else None

    @cached_property
    def events(self) -> tuple[ContactEvent, ...]:
        """The contacts as events, each with the witnesses that saw it (:func:`sim.execute.events.group_events`)."""
        return tuple(group_events(self.contacts))

    def series(self, max_samples: int = 2000) -> dict | None:
        """``times``, ``min_gap`` and ``tracking_error`` thinned for plots (:func:`sim.execute.series.thin`), or None."""
        if self.min_gap is None or self.tracking_error is None:
            return None
        from .series import thin

        arrays = {"times": self.times, "min_gap": self.min_gap, "tracking_error": self.tracking_error}
        return thin(arrays, max_samples)

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else math.inf

    @property
    def verdict(self) -> str:
        """One line: what happened."""
        parts = []
        if self.contacts:
            c = self.events[0]
            parts.append(f"{plural(len(self.events), 'contact')}, the first: {c.describe()}")
        if self.stopped:
            parts.append(f"stopped: {self.stopped}")
        if self.budget_exhausted_at is not None:
            parts.append(f"replan budget exhausted at t = {self.budget_exhausted_at:.3f} s"
                         + (" (sim.recovery.on_budget: continue)" if not self.budget_failed else ""))
        if self.reached_robots is not None and not self.reached and not self.stopped:
            working = [i for i in range(len(self.reached_robots)) if i not in self.failed]
            missed = [i for i in working if not self.reached_robots[i]]
            who = ", ".join(str(i) for i in missed[:10]) + (" ..." if len(missed) > 10 else "")
            parts.append(f"robots {who} end off target (worst {self.final_error:.3g})")
        m = 0 if self.reached_robots is None else len(self.reached_robots)
        if not self.contacts and not self.stopped and self.reached:
            parts.insert(0, "no contact, " + reached_phrase(bool(self.failed), self.parked))
        parts += run_notes(self.failed, self.parked, self.targets_filled, m, len(self.replans),
                           self.phase_margin_deg, advice=True)
        parts += timing_notes(self.drive_timing)
        if self.speed_warnings:
            parts.append(f"{plural(len(self.speed_warnings), 'speed warning')}, the first: {self.speed_warnings[0]}")
        if self.targets_total >= 0 and self.failed:  # without failures both rules agree
            parts.append(f"accept: {self.accept} ({self.targets_working} of {self.targets_total} targets hold "
                         "a working robot)")
        return "; ".join(parts)

    def to_dict(self) -> dict:
        """JSON-ready summary (no per-sample arrays)."""
        d = {
            "ok": self.ok,
            "contacts": len(self.events),
            "contacts_pymunk": sum(c.witness == "pymunk" for c in self.contacts),
            "contacts_monitor": sum(c.witness == "monitor" for c in self.contacts),
            "min_clearance": _finite(self.min_clearance),
            "min_clearance_time": _finite(self.min_clearance_time),
            "min_clearance_kind": self.min_clearance_kind,
            "min_clearance_pair": list(self.min_clearance_pair),
            "max_tracking_error": _finite(self.max_tracking_error),
            "reached": self.reached,
            "final_error": _finite(self.final_error),
            "sim_time_s": self.sim_time_s,
            "wall_time_s": self.wall_time_s,
            "realtime_factor": _finite(self.realtime_factor),
            "contact_list": [c.to_dict() for c in self.contacts[:_LIST_MAX]],
            "contact_events": [e.to_dict() for e in self.events[:_LIST_MAX]],
        }
        if len(self.events) > _LIST_MAX:
            d["contact_events_truncated"] = True
        if len(self.contacts) > _LIST_MAX:
            d["contact_list_truncated"] = True
        d["first_contact"] = self.contacts[0].to_dict() if self.contacts else None
        d["max_tracking_error_time"] = _finite(self.max_tracking_error_time)
        d["max_tracking_error_robot"] = self.max_tracking_error_robot
        if self.reached_robots is not None:
            d["reached_robots"] = [bool(v) for v in self.reached_robots]
        if self.masses is not None and len(self.masses):
            d["mass_range"] = [float(self.masses.min()), float(self.masses.max())]
        d["failed"] = list(self.failed)
        kinds = [x.kind for x in self.disturbances]
        d["disturbances"] = {
            "impulses": kinds.count("impulse"),
            "pushes": kinds.count("push"),
            "failures": kinds.count("failure"),
            "list": [x.to_dict() for x in self.disturbances[:_LIST_MAX]],
        }
        if len(self.disturbances) > _LIST_MAX:
            d["disturbances"]["list_truncated"] = True
        d["replans"] = [r.to_dict() for r in self.replans]
        d["stopped"] = self.stopped or None
        d["targets_filled"] = self.targets_filled
        d["phase_margin_deg"] = _finite(self.phase_margin_deg)
        d["accept"] = self.accept
        d["targets_working"] = self.targets_working
        d["budget_exhausted_at"] = self.budget_exhausted_at
        if self.drive != "holonomic":
            d["drive"] = self.drive
            d["drive_timing"] = self.drive_timing
        if self.speed_warnings:
            d["speed_warnings"] = list(self.speed_warnings)
        d["verdict"] = self.verdict
        return d



def assemble(witness, monitor, times, positions, tracking, reached, final_error, per_robot,
            *, sim_time, wall0, step_time, masses, failed, disturbances, replans, stopped,
            targets_filled, phase_margin_deg, accept="targets", targets_total=-1, targets_working=-1,
            budget_exhausted_at=None, on_budget="fail", headings=None, drive="holonomic",
            drive_timing=None) -> SimReport:
    contacts = sorted(
        witness.contacts() + monitor.contacts(),
        key=lambda c: (c.time, c.witness != "pymunk", c.kind, c.a, c.b),
    )
    if np.isfinite(tracking).any():
        flat = int(np.nanargmax(tracking))
        s, i = divmod(flat, tracking.shape[1])
        track, track_time, track_robot = float(tracking[s, i]), float(times[s]), int(i)
    else:
        track, track_time, track_robot = 0.0, float("nan"), -1
    min_gap = monitor.series
    for a in (times, positions, tracking, min_gap, per_robot, masses):
        a.setflags(write=False)
    return SimReport(
        contacts=tuple(contacts),
        min_clearance=monitor.min_gap,
        min_clearance_time=monitor.min_time,
        max_tracking_error=track,
        reached=reached,
        final_error=final_error,
        sim_time_s=sim_time,
        wall_time_s=_time.perf_counter() - wall0,
        times=times,
        positions=positions,
        min_clearance_kind=monitor.min_kind,
        min_clearance_pair=monitor.min_pair,
        step_time_s=step_time,
        min_gap=min_gap,
        tracking_error=tracking,
        max_tracking_error_time=track_time,
        max_tracking_error_robot=track_robot,
        reached_robots=per_robot,
        masses=masses,
        failed=tuple(failed),
        disturbances=tuple(disturbances),
        replans=tuple(replans),
        stopped=stopped,
        targets_filled=targets_filled,
        phase_margin_deg=phase_margin_deg,
        accept=accept,
        targets_total=targets_total,
        targets_working=targets_working,
        budget_exhausted_at=budget_exhausted_at,
        on_budget=on_budget,
        headings=headings,
        drive=drive,
        drive_timing=drive_timing,
        speed_warnings=tuple(getattr(witness, "speed_warnings", ())),
    )



def filled(final: np.ndarray, target: np.ndarray, tolerance: float) -> int:
    """How many targets have a robot within ``tolerance`` (a largest matching of robots to targets)."""
    from scipy.optimize import linear_sum_assignment

    target = np.asarray(target, float).reshape(-1, 2)
    far = np.linalg.norm(final[:, None, :] - target[None, :, :], axis=2) > tolerance
    rows, cols = linear_sum_assignment(far.astype(float))
    return int((~far[rows, cols]).sum())


def reached(final: np.ndarray, target: np.ndarray, tolerance: float, working: np.ndarray):
    """Match working robots to distinct targets at least total distance.

    Returns ``(all working robots within tolerance, worst matched distance,
    (m,) per-robot flags)``.
    """
    from scipy.optimize import linear_sum_assignment

    m = len(final)
    per = np.zeros(m, bool)
    target = np.asarray(target, float).reshape(-1, 2)
    rows_w = np.flatnonzero(working)
    if len(rows_w) == 0:
        return True, 0.0, per
    if len(target) < len(rows_w):
        return False, math.inf, per
    cost = np.linalg.norm(final[rows_w][:, None, :] - target[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    d = cost[rows, cols]
    per[rows_w[rows]] = d <= tolerance
    worst = float(d.max())  # rows_w is not empty, so neither is the matching
    return bool(worst <= tolerance), worst, per
