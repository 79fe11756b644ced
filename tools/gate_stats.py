"""The evidence behind the planner's relaxation gate: per start of every planned solve, what each search reaches.

For each episode of a sweep file (the same scenes as ``nextage-qp sweep FILE --seed S``), every solve the planner
makes with an accepted error and collision pairs is examined before it runs: from each of its starts (the current
joints, then the seeded random restarts, exactly the solve's own), one descent without collision rows and one with
them. A start counts as *reached* by a descent that comes within the accepted errors (the relaxed descent: within
``RELAXED_MARGIN`` times them, the gate's test). The table says how often the collision-aware descent reached the
targets from a start whose relaxed descent did not (the gate gives such a start up), and from a random start whose
relaxed answer went through a collision (given up too), against those whose relaxed answer was clear (kept).

Run: python tools/gate_stats.py configs/sweeps/push_cube.yaml --n 20 --seed 0
"""

from __future__ import annotations

import argparse
from collections import Counter

import nextage_qp as nq
from nextage_qp.ik import solve as solve_module
from nextage_qp.sweep.run import plan
from nextage_qp.sweep.spec import SweepSpec


def examine(ik, targets, q0, kwargs, counts: Counter) -> None:
    """Count, per start of one solve, (first start?, relaxed reached, relaxed clear, collision-aware reached)."""
    accept = kwargs["accept"]
    ik._prepare(kwargs.get("object_poses"), kwargs.get("allow", frozenset()))
    frames = [ik.frame(t.frame) for t in targets]
    starts = ik.starts(frames, q0)
    cap = kwargs.get("max_iters") or ik.config.max_iters
    margin = solve_module.RELAXED_MARGIN
    for k, q in enumerate(starts):
        _, _, pos, rot, _, _ = ik._descend(targets, frames, q, cap, ())
        aware = pos <= accept[0] and rot <= accept[1]
        _, q_relaxed, pos, rot, _, _ = ik._descend(targets, frames, q, cap, (), relaxed=True)
        relaxed = pos <= margin * accept[0] and rot <= margin * accept[1]
        ik.configuration.update(q_relaxed)
        clear = ik.collision.clear(ik.configuration.data)
        counts[(k == 0, relaxed, clear, aware)] += 1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep", help="sweep file, e.g. configs/sweeps/push_cube.yaml")
    parser.add_argument("--n", type=int, default=20, help="episodes (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="the sweep's seed (default 0)")
    args = parser.parse_args()
    spec = SweepSpec(args.sweep)
    counts: Counter = Counter()
    original = solve_module.OfflineSolver.solve

    def solve(self, targets, q0, **kwargs):
        if kwargs.get("accept") is not None and self.collision is not None and not kwargs.get("extra_tasks"):
            examine(self, targets, q0, kwargs, counts)
        return original(self, targets, q0, **kwargs)

    solve_module.OfflineSolver.solve = solve  # type: ignore[method-assign]
    ran = 0
    for task in plan(spec, args.seed, range(args.n)):
        try:
            nq.run_task(task.base, overrides=task.overrides)
            ran += 1
        except nq.ConfigError:
            pass  # a refused scene: nothing planned
    print(f"{args.sweep}: {ran} episodes run of {args.n}, seed {args.seed}; starts of the planner's gated solves:")

    def line(label: str, keep) -> None:
        rows = [(key, n) for key, n in counts.items() if keep(*key)]
        total = sum(n for _, n in rows)
        reached = sum(n for key, n in rows if key[3])
        print(f"  {label:70s} {total:6d} starts, collision-aware descent reached the targets from {reached}")

    line("relaxed descent missed (first start)", lambda first, r, c, a: first and not r)
    line("relaxed descent missed (random restart)", lambda first, r, c, a: not first and not r)
    line("relaxed descent reached, through a collision (random restart)",
         lambda first, r, c, a: not first and r and not c)
    line("relaxed descent reached, clear of every pair (random restart)", lambda first, r, c, a: not first and r and c)
    line("relaxed descent reached, through a collision (first start)", lambda first, r, c, a: first and r and not c)
    line("relaxed descent reached, clear of every pair (first start)", lambda first, r, c, a: first and r and c)


if __name__ == "__main__":
    main()
