"""The static-gain controller of ``scenarios/lti/static-gain.toml`` on the service
side of the contract: ``u_k = -K y_k`` with K = 2 (an LTI controller with no state and
D = [[-K]]: u = D y), answered compute-first; with ``--send-ahead`` the delayed gain
``u_{k+1} = -K y_k`` (the LTI controller A = [[0]], B = [[1]], C = [[-K]], D = [[0]]),
published ahead as the input of sample k + 1.

    python static_gain_controller.py --rig first-order-lockstep [--send-ahead]

A refused connection prints ``python controller: <reason>`` and exits with 1. It stops
after the plant's last sample and prints how many samples it answered.
"""

import argparse
import sys

from adaptive_rig import ChannelCounts, ConnectError, Timing
from adaptive_rig.controller import Controller


def main() -> int:
    """Runs the controller; returns the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ChannelCounts.add_arguments(ap)
    ap.add_argument("--gain", type=float, default=2.0, help="K of u = -K y")
    ap.add_argument("--send-ahead", action="store_true", help="u_{k+1} = -K y_k, sent ahead")
    args = ap.parse_args()
    d = -args.gain
    try:
        counts = ChannelCounts.from_arguments(args)
        ctl = Controller(
            args.rig,
            counts,
            round(args.period * 1e9),
            peer_timeout_s=args.peer_timeout,
            contract_version=args.contract_version,
            timing=Timing.SEND_AHEAD if args.send_ahead else Timing.COMPUTE_FIRST,
        )
    except (ConnectError, ValueError) as e:
        print(f"python controller: {e}", file=sys.stderr, flush=True)
        return 1
    print("[python controller] connected", file=sys.stderr, flush=True)
    n = ctl.serve(lambda m: [d * m.y[0]] * counts.n_u)
    p50, p99 = ctl.response_percentiles(50, 99)
    print(
        f"[python controller] done: {n} answered, {ctl.stall_acks} stall(s) acknowledged, "
        f"{ctl.ports.foreign_samples} foreign sample(s) refused; response time "
        f"(publish - sample) p50 {p50} ns, p99 {p99} ns",
        file=sys.stderr,
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
