"""The ``scara-c11`` command."""

from __future__ import annotations

import argparse
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    from scara_gym import ENV_VERSIONS, LATEST_ENV_ID, __version__

    parser = argparse.ArgumentParser(prog="scara-c11", description="ARGESIM C11 SCARA robot benchmark")
    parser.add_argument("--version", action="version", version=f"scara-c11 (scara_gym) {__version__}")
    commands = parser.add_subparsers(dest="command", required=True)
    rep = commands.add_parser("reproduce", help="the seed paper's tables beside ours, and its figures")
    rep.add_argument("--out", type=Path, default=Path("c11-results"), help="folder for the PNG figures")
    rep.add_argument("--repeats", type=int, default=5, help="timing repeats of task a (best of)")
    bench = commands.add_parser("bench", help="speed figures, measured side by side")
    bench.add_argument("--quick", action="store_true", help="small sizes: a smoke check")
    bench.add_argument("--gpu-only", action="store_true", help="only the GPU section (the CUDA vector env)")
    accuracy = commands.add_parser("accuracy", help="errors at given tolerances against a tight run of the same env")
    accuracy.add_argument("--episodes", type=int, default=200, help="random episodes (default 200)")
    accuracy.add_argument("--seed", type=int, default=0, help="seed of the episode plans")
    v1 = ENV_VERSIONS[LATEST_ENV_ID]
    accuracy.add_argument("--rtol", type=float, default=v1["rtol"], help="relative tolerance under test "
                          f"(default: {LATEST_ENV_ID}'s {v1['rtol']:g})")
    accuracy.add_argument("--atol", type=float, default=v1["atol"], help="absolute tolerance under test "
                          f"(default: {LATEST_ENV_ID}'s {v1['atol']:g})")
    args = parser.parse_args(argv)
    if args.command == "reproduce":
        if args.repeats < 1:
            parser.error(f"--repeats must be >= 1, got {args.repeats}")
        from scara_gym.benchmark.reproduce import reproduce
        reproduce(out=args.out, repeats=args.repeats)
    elif args.command == "accuracy":
        if args.episodes < 1:
            parser.error(f"--episodes must be >= 1, got {args.episodes}")
        if args.seed < 0:
            parser.error(f"--seed must be >= 0, got {args.seed}")
        from scara_gym.model import checks
        for name in ("rtol", "atol"):
            try:
                checks.tolerance(name, getattr(args, name))
            except ValueError as error:
                parser.error(f"--{error}")
        from scara_gym.benchmark.accuracy import main as accuracy_main
        accuracy_main(args.episodes, args.seed, args.rtol, args.atol)
    elif args.command == "bench":
        from scara_gym.benchmark.bench import main as bench_main
        bench_main(quick=args.quick, gpu_only=args.gpu_only)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
