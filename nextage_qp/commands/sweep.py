"""``nextage-qp sweep SWEEP.yaml``: run a task over randomised scenes and report how often it succeeds."""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nextage_qp.commands.common import (
    PLAIN_PROGRESS_S,
    PLOT_SUFFIXES,
    SEED,
    add_backend_args,
    check_backend_args,
    out_console,
    output_file,
    print_json,
)
from nextage_qp.errors import ConfigError
from nextage_qp.io.outputs import refuse_overwriting
from nextage_qp.sweep.episode import UNRATED

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import (
        Progress,
    )

    from nextage_qp.sweep.episode import Episode
    from nextage_qp.sweep.spec import SweepSpec


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` subcommand."""
    p = sub.add_parser("sweep", help="run a task over randomised scenes (success rate with its 95 %% interval)")
    p.add_argument("sweep", help="sweep YAML, e.g. configs/sweeps/push_cube.yaml")
    p.add_argument("--n", type=int, help="episodes 0..N-1 (required unless --only)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a base-config key in every episode, e.g. --set timing.ctrl_dt=0.01 (repeatable)")
    p.add_argument("--seed", type=SEED, default=0, help="sweep seed: episode i depends on (seed, i) only (default 0)")
    add_backend_args(p, "parallel episodes (default: the CPU count, or the Ray cluster's)")
    p.add_argument("--out", type=Path, help="directory of the episode records (default runs/sweeps/NAME-seedS)")
    p.add_argument("--json", action="store_true",
                   help="print the summary as JSON on standard output, as run --json prints its record (the summary is "
                        "always written to OUT/summary.json too)")
    p.add_argument("--plot", type=output_file(*PLOT_SUFFIXES), metavar="PNG",
                   help="write the error CDF and error against each parameter")
    p.add_argument("--resume", action="store_true", help="continue the sweep in --out, skipping finished episodes")
    p.add_argument("--only", metavar="I,J,...", help="run only these episode indices (e.g. to replay a failure)")
    p.set_defaults(func=run)


def _indices(args: argparse.Namespace) -> list[int]:
    if args.only is not None:
        try:
            only = [int(x) for x in args.only.split(",") if x.strip()]
        except ValueError:
            raise ConfigError(f"--only {args.only!r}: expected episode indices like 3,17,42") from None
        if not only or min(only) < 0 or max(only) >= 1_000_000:
            raise ConfigError(f"--only {args.only!r}: expected episode indices from 0 to 999999 like 3,17,42")
        return sorted(set(only))
    if args.n is None:
        raise ConfigError("--n is required (the number of episodes), unless --only names episodes")
    if not 1 <= args.n <= 1_000_000:
        raise ConfigError(f"--n must be between 1 and 1000000, got {args.n}")
    return list(range(args.n))


class _Progress:
    """A bar with episodes done, running success rate and ETA; plain lines every few seconds off a terminal."""

    def __init__(self, name: str, total: int, done: list[Episode]) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.name, self.total = name, total
        self.done = len(done)
        self.success = sum(e.status == "success" for e in done)
        self.ran = sum(e.status not in UNRATED for e in done)
        self.console = Console(stderr=True)
        self.bar: Progress | None = None
        self.t0 = self.last = time.monotonic()
        self.start_done = self.done
        if self.console.is_terminal:
            self.bar = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                                TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TextColumn("ETA"),
                                TimeRemainingColumn(), console=self.console, transient=True)
            self.task = self.bar.add_task(name, total=total, completed=self.done, rate=self._rate())

    def _rate(self) -> str:
        return f"success {100 * self.success / self.ran:.1f} %" if self.ran else "success -"

    def __enter__(self) -> _Progress:
        if self.bar is not None:
            self.bar.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.stop()

    def update(self, episode: Episode) -> None:
        self.done += 1
        self.success += episode.status == "success"
        self.ran += episode.status not in UNRATED
        if self.bar is not None:
            self.bar.update(self.task, completed=self.done, rate=self._rate())
            return
        now = time.monotonic()
        if now - self.last >= PLAIN_PROGRESS_S or self.done == self.total:
            self.last = now
            rate = (self.done - self.start_done) / max(now - self.t0, 1e-9)
            eta = (self.total - self.done) / rate if rate > 0 else float("nan")
            print(f"sweep {self.name}: {self.done}/{self.total} episodes, {self._rate()} ({self.success}/{self.ran}), "
                  f"{60 * rate:.1f} episodes/min, ETA {eta / 60:.1f} min", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    """Run the sweep; exit 0 when every episode has a record (whatever its outcome), 130 when interrupted.

    Exit 1 when no episode ran to its end (every one refused or an error): nothing was measured.
    """
    from nextage_qp.sweep.run import plan, run_sweep
    from nextage_qp.sweep.spec import SweepSpec
    from nextage_qp.sweep.store import SweepStore, default_folder
    from nextage_qp.sweep.summary import write_summary

    check_backend_args(args)
    indices = _indices(args)
    spec = SweepSpec(args.sweep, args.overrides)
    workers = args.workers or (None if args.backend == "ray" else os.cpu_count() or 1)
    if args.out is not None:
        out = args.out
    elif args.only is not None:
        out = Path(tempfile.mkdtemp(prefix=f"nextage-sweep-{spec.name}-"))
    else:
        out = default_folder(spec, args.seed)
    refuse_overwriting({"the sweep's record": out / "sweep.json", "the sweep's episodes": out / "episodes.jsonl",
                        "--plot": args.plot},
                       {"the sweep file": spec.path, "its base config": spec.base_path})
    store = SweepStore(out, spec, args.seed, resume=args.resume)
    tasks = plan(spec, args.seed, indices)
    already = [store.done[t.index] for t in tasks if t.index in store.done]
    t0 = time.monotonic()
    try:
        with _Progress(spec.name, len(tasks), already) as progress:
            episodes = run_sweep(tasks, store=store, workers=min(workers or len(tasks), len(tasks)) or 1,
                                 backend=args.backend, ray_address=args.ray_address, on_episode=progress.update)
    except KeyboardInterrupt:
        store.close()
        kept = sum(t.index in store.done for t in tasks)
        print(f"nextage-qp sweep: interrupted; {kept} of {len(tasks)} episodes are on disk in {out}; continue with "
              f"the same command and --resume", file=sys.stderr)
        return 130
    store.close()
    wall = time.monotonic() - t0
    summary = write_summary(out, spec, args.seed, episodes, session_episodes=len(episodes) - len(already),
                            session_wall_s=wall)
    failed = _write_outputs(args, spec, summary, episodes)
    if args.json:
        print_json(summary)
    else:
        _print_summary(summary, out_console(width=120), only=args.only is not None, episodes=episodes)
    if failed:  # the records and the summary above are kept; only these files are missing
        print(f"nextage-qp sweep: error: {'; '.join(failed)}", file=sys.stderr)
        return 2
    statuses = [e.status for e in episodes]
    if statuses and all(s in ("refused", "error") for s in statuses):  # nothing measured: say so to a script too
        print(f"nextage-qp sweep: error: no episode ran to its end ({statuses.count('refused')} refused, "
              f"{statuses.count('error')} errors; the summary above says why)", file=sys.stderr)
        return 1
    return 0


def _write_outputs(args: argparse.Namespace, spec: SweepSpec, summary: dict[str, Any],
                   episodes: list[Any]) -> list[str]:
    """Write ``--plot``; one that cannot be written does not stop the summary."""
    failed = []
    if args.plot:
        from nextage_qp.viz.sweep import plot_sweep

        try:
            plot_sweep(spec, episodes, args.plot)
        except OSError as exc:
            failed.append(f"--plot {args.plot}: cannot write: {exc.strerror or exc}")
    return failed


def _mm(value: float | None) -> str:
    return "-" if value is None else f"{value * 1e3:.2f}"


def _print_summary(s: dict[str, Any], console: Console, *, only: bool, episodes: list[Episode]) -> None:
    from rich.markup import escape
    from rich.table import Table

    from nextage_qp.estimation.report import SHOVE_SETTLE_S
    from nextage_qp.sweep.summary import BINS

    rate = s["success_rate"]
    lo, hi = s["success_rate_ci95"]
    sets = "".join(f" --set {item}" for item in s["set"])
    head = (f"{s['sweep']}{sets} (seed {s['seed']}): {s['counts']['success']}/{s['ran']} succeed = "
            + ("-" if rate is None else f"{100 * rate:.1f} %") + f" (95 % CI {100 * lo:.1f}-{100 * hi:.1f} %)")
    console.print(head, markup=False)
    counts = ", ".join(f"{k} {v}" for k, v in s["counts"].items())
    if s["retried"] or s["counts"]["lost"]:  # the machine's failures, not the task's: in no rate
        counts += f"; {s['retried']} run again after their process died, {s['counts']['lost']} lost twice"
    epm = s["episodes_per_minute"] if s["session"]["episodes_run"] else None
    console.print(f"episodes: {s['episodes']} ({counts}); {'-' if epm is None else f'{epm:.1f}'} episodes/min; "
                  f"records in {s['out']}", markup=False)
    table = Table(title="object error [mm]", title_justify="left")
    for col in ("", "median", "p90", "p99", "max"):
        table.add_column(col, justify="right")
    for key, label in (("object_error_m", "as judged for success"), ("object_error_xy_m", "x-y")):
        q = s[key]
        table.add_row(label, _mm(q["median"]), _mm(q["p90"]), _mm(q["p99"]), _mm(q["max"]))
    console.print(table)
    if (est := s.get("estimation")) is not None:
        ratios = ", ".join(f"{est[f'estimate_over_{k}']:.2f} of {k}" for k in ("raw", "held")
                           if est.get(f"estimate_over_{k}") is not None)
        console.print(f"object estimate RMS {_mm(est['estimate_rms_m'])} mm ({ratios}); raw {_mm(est['raw_rms_m'])} "
                      f"mm, held {_mm(est['held_rms_m'])} mm; {est['dropouts']}/{est['measurements']} measurements "
                      f"dropped; {est['shoves']} shoves", markup=False)
        if est.get("camera_unoccluded"):
            rate = 100 * est["camera_detected_of_unoccluded"]
            console.print(f"camera: detected in {est['camera_unoccluded_ok']}/{est['camera_unoccluded']} frames with "
                          f"the object in view and uncovered ({rate:.1f} %); estimate RMS then "
                          f"{_mm(est['estimate_unoccluded_rms_m'])} mm", markup=False)
        if est["shoves"] and est.get("estimate_outside_shoves_over_raw") is not None:
            console.print(f"outside the {SHOVE_SETTLE_S:g} s after each shove ({est['shove_ticks']} ticks): estimate "
                          f"RMS {_mm(est['estimate_outside_shoves_rms_m'])} mm "
                          f"({est['estimate_outside_shoves_over_raw']:.2f} of raw)", markup=False)
    if (mb := s.get("mobile_base")) is not None:
        drift, drive = mb["odometry_drift_m"], mb["drive_time_s"]
        console.print(f"base: odometry drift median {_mm(drift['median'])} mm, max {_mm(drift['max'])} mm; drive time "
                      f"median {drive['median'] or 0:.1f} s, max {drive['max'] or 0:.1f} s; largest lateral speed "
                      f"{_mm(mb['max_lateral_speed_m_s'])} mm/s; {mb['episodes_sliding']}/{mb['episodes']} episodes "
                      "with ticks sliding sideways (> 10 mm/s)", markup=False)
    for row in s["by_target_clearance"]:
        lo, hi = row["success_rate_ci95"]
        rate = "-" if row["success_rate"] is None else f"{100 * row['success_rate']:.1f} %"
        console.print(f"targets {row['targets']}: {row['successes']}/{row['episodes']} succeed = {rate} "
                      f"(95 % CI {100 * lo:.1f}-{100 * hi:.1f} %)", markup=False)
    if s["failures_by_phase"]:
        console.print("failures by phase: " + ", ".join(f"{k}: {v}" for k, v in s["failures_by_phase"].items()),
                      markup=False)
        console.print("failures by criterion: " + ", ".join(f"{k}: {v}" for k, v in
                                                            s["failures_by_criterion"].items()), markup=False)
    if not only:
        bins = Table(title=f"success rate by parameter ({BINS} equal bins of its range, low to high)",
                     title_justify="left")
        bins.add_column("parameter")
        bins.add_column("range")
        for b in range(BINS):
            bins.add_column(f"bin {b + 1}", justify="right")
        rows: dict[str, list[dict[str, Any]]] = {}
        for row in s["by_parameter"]:
            rows.setdefault(row["parameter"], []).append(row)
        for name, cells in rows.items():
            numeric = len(cells) == BINS and cells[0]["bin"].startswith("[")
            span = (f"{cells[0]['bin'][1:].split(',')[0]} .. {cells[-1]['bin'].split(',')[1].strip()[:-1]}"
                    if numeric else "choice")
            shown = [f"{c['successes']}/{c['episodes']}" for c in cells]
            if not numeric:
                shown = [f"{c['bin']}: {x}" for c, x in zip(cells, shown, strict=True)]
            bins.add_row(name.removeprefix("scene.").removeprefix("poses."), escape(span), *shown[:BINS])
        console.print(bins)
    if only:
        for ep in episodes:
            err = (ep.result or {}).get("object_error_xy_m")  # as the success criterion judges it
            console.print(f"episode {ep.index}: {ep.status}; object error (x-y) {_mm(err)} mm"
                          + (f"; {ep.reason}" if ep.reason else ""), markup=False)
    failed = s["failed"]
    if failed:
        console.print(f"{len(failed)} episode(s) not successful; replay one alone with "
                      "(add --plot/--video/--rerun/--viewer):", markup=False)
        for f in failed[:10]:
            console.print(f"  [{f['index']}] {f['status']}: {f['reason']}", markup=False, soft_wrap=True)
            console.print(f"      {f['replay']['run']}", markup=False, soft_wrap=True)
        if len(failed) > 10:
            console.print(f"  ... {len(failed) - 10} more in the summary JSON ({s['out']}/summary.json)", markup=False)
