"""A first-order plant G(s) = 1/(s + p) on the plant side of the contract, in lockstep.

The plant of ``scenarios/first-order-lockstep.toml`` (p = 5, T = 1 ms, x(0) = 1, no noise),
discretized exactly under a zero-order hold:

    x_{k+1} = e^{-pT} x_k + (1 - e^{-pT}) / p * u_k,   y_k = z_k = x_k

Every used ``y`` and ``z`` channel carries ``x``; the first input drives it. Writes a CSV
trace ``k,y0,u0`` (the input applied for sample k) with ``--trace``, the counters as JSON
with ``--report``. A refused connection prints ``python plant: <reason>`` and exits with 1.

    python first_order_plant.py --rig first-order-lockstep --steps 2000 --trace trace.csv
"""

import argparse
import json
import sys

import numpy as np

from adaptive_rig import ChannelCounts, ConnectError
from adaptive_rig.plant import Plant, PlantGaveUp


def main() -> int:
    """Runs the plant; returns the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ChannelCounts.add_arguments(ap)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--pole", type=float, default=5.0, help="p of 1/(s + p)")
    ap.add_argument("--x0", type=float, default=1.0)
    ap.add_argument("--mode", default="lockstep", choices=["lockstep", "real-time"])
    ap.add_argument("--deadline", type=float, default=0.5, help="real time: input applied at t_k + dT")
    ap.add_argument("--trace", default=None)
    ap.add_argument("--report", default=None)
    args = ap.parse_args()

    p, t = args.pole, args.period
    a = np.exp(-p * t)
    b = (1.0 - a) / p
    period_ns = round(t * 1e9)
    try:
        counts = ChannelCounts.from_arguments(args)
        plant = Plant(
            args.rig,
            counts,
            period_ns,
            mode=args.mode,
            deadline=args.deadline,
            peer_timeout_s=args.peer_timeout,
            contract_version=args.contract_version,
        )
    except (ConnectError, ValueError) as e:
        print(f"python plant: {e}", file=sys.stderr, flush=True)
        return 1
    print("[python plant] connected", file=sys.stderr, flush=True)
    rows = []
    x = float(args.x0)
    try:
        for k in range(args.steps):
            u = plant.step(
                y=[x] * args.n_y, z=[x] * args.n_z, r=[0.0] * args.n_r, last=(k + 1 == args.steps)
            )
            rows.append((k, x, u[0] if u else 0.0))
            x = float(a * x + b * (u[0] if u else 0.0))
    except PlantGaveUp as e:
        print(f"python plant: {e}", file=sys.stderr, flush=True)
        return 1
    finally:
        if args.trace:
            with open(args.trace, "w") as f:
                f.write("k,y0,u0\n")
                f.writelines(f"{k},{y!r},{u!r}\n" for k, y, u in rows)
        if args.report:
            with open(args.report, "w") as f:
                json.dump(plant.report.as_dict(), f, indent=1)
    print(f"[python plant] done: {plant.report}", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
