"""Trajectories out: a plan as samples (CSV, JSON) or as exact piecewise polynomials.

A plan's step ``k`` moves robot ``i`` from ``a = waypoints[k][i]`` by
``d = waypoints[k+1][i] - a`` along ``s(tau / T)``, ``s(u) = 10u^3 - 15u^4
+ 6u^5``, for ``tau`` in ``[0, T]``, ``T = durations[k]`` [s]; so each
coordinate is, exactly, the degree-5 polynomial
``a + 10 d/T^3 tau^3 - 15 d/T^4 tau^4 + 6 d/T^5 tau^5`` (a robot that stands
still in a step: the constant ``a``).

* :func:`samples`, :func:`to_csv`, :func:`to_json`: positions and
  velocities [units, units/s] of every robot at ``i / rate`` s for
  ``i = 0, 1, ...`` below the makespan, and at the makespan itself; the
  numbers are :meth:`planner.Plan.sample`'s, written so that they read back
  exactly (shortest round-trip decimal form).  CSV columns
  ``robot,t,x,y,vx,vy``; JSON ``{"rate", "makespan", "robots": [{"t", "x",
  "y", "vx", "vy"}, ...]}``.
* :func:`poly_pieces`, :func:`to_poly_csv`: one polynomial piece per step
  per robot in the CSV format that Crazyswarm's ``uploadTrajectory`` reads
  (``uav_trajectory.Trajectory.loadcsv``): a header, then rows
  ``duration,x^0..x^7,y^0..y^7,z^0..z^7,yaw^0..yaw^7`` (8 coefficients per
  axis, lowest power first, in the piece's own time from 0); ``z`` is the
  constant ``height``, yaw 0.
"""

from __future__ import annotations

import json

import numpy as np

__all__ = ["MAX_SAMPLES", "POLY_HEADER", "cmd_export", "eval_piece", "poly_pieces", "sample_times", "samples", "shifted",
           "to_csv", "to_json", "to_poly_csv"]

MAX_SAMPLES = 20_000_000
"""The most (robot, time) samples one export writes."""

POLY_HEADER = "duration," + ",".join(f"{a}^{p}" for a in ("x", "y", "z", "yaw") for p in range(8))
"""The header row of a Crazyswarm polynomial trajectory CSV."""


def shifted(plan, origin):
    """The plan with ``origin`` ``(x, y)`` added to every waypoint (the same plan when it is 0 0):
    trajectories in the frame of a map whose lower-left corner lies there (a ROS map's
    ``origin``); durations, and so velocities, unchanged."""
    from dataclasses import replace

    o = np.asarray(origin, float).reshape(2)
    if not o.any():
        return plan
    return replace(plan, waypoints=np.asarray(plan.waypoints) + o)


def sample_times(makespan: float, rate: float) -> np.ndarray:
    """``i / rate`` for every ``i`` with ``i / rate < makespan``, then ``makespan`` [s]."""
    n = int(np.floor(makespan * rate)) + 1
    ts = np.arange(n, dtype=float) / rate
    ts = ts[ts < makespan - 1e-9]
    return np.append(ts, makespan)


def samples(plan, rate: float):
    """``(ts, pos, vel)``: times ``(T,)`` and positions, velocities ``(T, m, 2)`` at ``rate`` Hz."""
    ts = sample_times(plan.makespan, rate)
    pos, vel, _acc = plan.sample(ts)
    return ts, pos, vel


def _r(v) -> str:
    return repr(float(v))


def to_csv(plan, rate: float) -> str:
    """The samples as CSV, ``robot,t,x,y,vx,vy``, robot by robot, time ascending."""
    ts, pos, vel = samples(plan, rate)
    lines = ["robot,t,x,y,vx,vy"]
    tt = [_r(t) for t in ts]
    for i in range(plan.m):
        for j, t in enumerate(tt):
            lines.append(f"{i},{t},{_r(pos[j, i, 0])},{_r(pos[j, i, 1])},{_r(vel[j, i, 0])},{_r(vel[j, i, 1])}")
    return "\n".join(lines) + "\n"


def to_json(plan, rate: float) -> str:
    """The samples as JSON: ``{"rate", "makespan", "robots": [{"t", "x", "y", "vx", "vy"}]}``."""
    ts, pos, vel = samples(plan, rate)
    t = ts.tolist()
    robots = [{"t": t, "x": pos[:, i, 0].tolist(), "y": pos[:, i, 1].tolist(),
               "vx": vel[:, i, 0].tolist(), "vy": vel[:, i, 1].tolist()} for i in range(plan.m)]
    return json.dumps({"rate": rate, "makespan": plan.makespan, "robots": robots}, allow_nan=False) + "\n"


def poly_pieces(plan, height: float = 0.0) -> np.ndarray:
    """``(m, K, 33)``: per robot and step, the duration and the 4 x 8 coefficients (x, y, z, yaw)."""
    w = plan.waypoints
    dur = plan.durations
    m, k = plan.m, plan.steps
    out = np.zeros((m, k, 33))
    if k == 0:
        return out
    a = w[:-1]  # (K, m, 2)
    d = w[1:] - w[:-1]
    T = dur[:, None, None]
    coef = np.zeros((k, m, 2, 8))
    coef[..., 0] = a
    coef[..., 3] = 10.0 * d / T**3
    coef[..., 4] = -15.0 * d / T**4
    coef[..., 5] = 6.0 * d / T**5
    out[:, :, 0] = dur[None, :]
    out[:, :, 1:9] = coef[:, :, 0].transpose(1, 0, 2)
    out[:, :, 9:17] = coef[:, :, 1].transpose(1, 0, 2)
    out[:, :, 17] = height
    return out


def to_poly_csv(plan, robot: int, height: float = 0.0, pieces: np.ndarray | None = None) -> str:
    """Robot ``robot``'s trajectory as a Crazyswarm polynomial CSV (see the module docstring)."""
    p = poly_pieces(plan, height) if pieces is None else pieces
    rows = [POLY_HEADER] + [",".join(_r(v) for v in row) for row in p[robot]]
    return "\n".join(rows) + "\n"


def eval_piece(coefficients, tau):
    """Value and first derivative of ``sum c[p] tau^p`` (``c``: 8 coefficients, lowest first)."""
    c = np.asarray(coefficients, float)
    tau = np.asarray(tau, float)
    value = np.polynomial.polynomial.polyval(tau, c)
    deriv = np.polynomial.polynomial.polyval(tau, np.polynomial.polynomial.polyder(c))
    return value, deriv


def cmd_export(args) -> int:
    """``swarmform export``: write the trajectories; exit 0 (wrong input raised as errors)."""
    import sys
    from pathlib import Path

    from planner.plan import note_ignored, read_plan_file

    from ..errors import InputError
    from .files import check_out_dir, check_out_file
    from .media import atomic_path

    plan_path = Path(args.plan)
    if args.format == "poly":
        folder = Path(args.output) if args.output else plan_path.with_name(plan_path.stem + "-poly")
        check_out_dir(folder, "-o")
    elif args.output:
        check_out_file(args.output, "-o")
    plan, extra = read_plan_file(plan_path)
    note_ignored(plan_path, extra)
    plan = shifted(plan, args.origin if args.origin is not None else extra.get("origin", (0.0, 0.0)))
    if args.format == "poly":
        pieces = poly_pieces(plan, args.height)
        folder.mkdir(parents=True, exist_ok=True)
        for i in range(plan.m):
            with atomic_path(folder / f"robot{i:03d}.csv") as tmp:
                tmp.write_text(to_poly_csv(plan, i, pieces=pieces), encoding="utf-8")
        from ..words import plural

        print(f"wrote {plural(plan.m, 'polynomial trajectory', 'polynomial trajectories')} ({plural(plan.steps, 'piece')} each) "
              f"to {folder}/robotNNN.csv")
        return 0
    n = (int(plan.makespan * args.rate) + 2) * plan.m  # at most this many; counted before any is made
    if n > MAX_SAMPLES:
        raise InputError(f"--rate: {args.rate:g} Hz over {plan.makespan:.1f} s for {plan.m} robots makes {n} "
                         f"samples, more than {MAX_SAMPLES}; lower the rate")
    text = (to_csv if args.format == "csv" else to_json)(plan, args.rate)
    if not args.output:
        sys.stdout.write(text)
        return 0
    with atomic_path(args.output) as tmp:
        tmp.write_text(text, encoding="utf-8")
    print(f"wrote {args.output} ({plan.m} robots, {len(sample_times(plan.makespan, args.rate))} samples each "
          f"at {args.rate:g} Hz)")
    return 0
