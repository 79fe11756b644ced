"""A sweep from Python: randomised push scenes on a process pool, and the summary the CLI prints.

    python examples/sweep_from_python.py [--episodes 6] [--workers 2]

The workers are spawned processes that import this script again: the sweep runs under ``if __name__ == "__main__"``.
"""

import argparse
import tempfile
from pathlib import Path

import nextage_qp as nq

ROOT = Path(__file__).resolve().parents[1]  # the repository: its configs


def main() -> None:
    """Run the sweep and print its summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=6)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    summary = nq.run_sweep(ROOT / "configs" / "sweeps" / "push_cube.yaml", episodes=args.episodes, seed=0,
                           workers=args.workers, out=tempfile.mkdtemp())
    lo, hi = summary["success_rate_ci95"]
    print(f"{summary['counts']['success']}/{summary['ran']} succeed = {100 * summary['success_rate']:.1f} % "
          f"(95 % CI {100 * lo:.1f}-{100 * hi:.1f} %); median error "
          f"{summary['object_error_m']['median'] * 1e3:.2f} mm; {summary['episodes_per_minute']:.1f} episodes/min")
    for failure in summary["failed"]:  # each with the command that replays it alone
        print(f"  [{failure['index']}] {failure['status']}: {failure['reason']}\n    {failure['replay']['run']}")


if __name__ == "__main__":
    main()
