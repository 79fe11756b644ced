"""``nextage-qp tune STUDY.yaml``: search gains or task keys with Optuna; check the best on held-out scenes."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nextage_qp.commands.common import add_backend_args, check_backend_args, out_console
from nextage_qp.errors import ConfigError

if TYPE_CHECKING:
    from rich.console import Console


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``tune`` subcommand."""
    p = sub.add_parser("tune", help="tune gains or task keys with Optuna over a sweep's episodes or step responses")
    p.add_argument("study", help="study YAML, e.g. configs/studies/pd_gains.yaml")
    p.add_argument("--trials", type=int, help="complete trials the study should hold (default: the study file's)")
    add_backend_args(p, "parallel episodes per trial (default: the study file's, else CPUs)")
    p.add_argument("--storage", help="Optuna storage URL shared by several runs (default: sqlite in --out)")
    p.add_argument("--out", type=Path, help="output folder (default runs/studies/NAME)")
    p.add_argument("--resume", action="store_true", help="continue the study in the storage")
    p.set_defaults(func=run)


def _check(args: argparse.Namespace, default_trials: int) -> int:
    trials = default_trials if args.trials is None else args.trials
    if not 1 <= trials <= 100_000:
        raise ConfigError(f"--trials must be between 1 and 100000, got {trials}")
    check_backend_args(args)
    return trials


def _out_dir(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot create the directory ({exc.strerror})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ConfigError(f"--out {out}: the directory is not writable")


class _Progress:
    """One line per trial: its value and account, the best so far, the time per trial."""

    def __init__(self, total: int, done: int) -> None:
        from rich.console import Console

        self.total, self.done = total, done
        self.console = Console(stderr=True, highlight=False)

    def __call__(self, trial: Any, score: Any, seconds: float) -> None:
        self.done += 1
        values = [(t.value, t.number) for t in trial.study.trials if t.value is not None]
        best_value, best_number = min([*values, (score.value, trial.number)])
        base = " (base)" if trial.user_attrs.get("base") else ""
        self.console.print(f"trial {trial.number}{base} [{self.done}/{self.total}]: {score.value:.5g}; {score.line}; "
                           f"{seconds:.1f} s | best {best_value:.5g} (trial {best_number})",
                           markup=False, soft_wrap=True)


def _not_anothers(out: Path, name: str) -> None:
    """Refuse an ``--out`` that holds a sweep's records or another study's outputs (its summary.json is rewritten)."""
    if (out / "sweep.json").is_file() or (out / "episodes.jsonl").is_file():
        raise ConfigError(f"--out {out}: holds a sweep's records (sweep.json, episodes.jsonl), which the study's "
                          "outputs would overwrite; choose another --out")
    summary = out / "summary.json"
    if summary.is_file():
        try:
            doc = json.loads(summary.read_text())
        except (OSError, ValueError):
            doc = None
        owner = doc.get("study") if isinstance(doc, dict) else None
        if owner != name:
            what = f"study {owner!r}'s outputs" if isinstance(owner, str) else "a summary.json this study did not write"
            raise ConfigError(f"--out {out}: holds {what}, which study {name!r} would overwrite; choose another --out")


def run(args: argparse.Namespace) -> int:
    """Run the study; exit 0 when it holds the requested trials and its outputs are written, 130 on Ctrl-C."""
    from nextage_qp.sweep.backends import local_pool, ray_init
    from nextage_qp.tune.report import finish
    from nextage_qp.tune.study import Study, open_storage, open_study, optimize

    study = Study(args.study)
    trials = _check(args, study.file.trials)
    out = args.out or Path("runs") / "studies" / study.name
    _not_anothers(out, study.name)
    _out_dir(out)
    url = args.storage or f"sqlite:///{(out / 'study.db').resolve()}"
    storage = open_storage(url)
    s = open_study(study, storage, resume=args.resume, where=args.storage or str(out / "study.db"))
    workers = args.workers or study.file.workers or (None if args.backend == "ray" else os.cpu_count() or 1)
    started_ray, pool = False, None
    if args.backend == "ray":
        started_ray = ray_init(workers, args.ray_address)
    else:
        pool = local_pool(workers or 1)
    from optuna.trial import TrialState

    done = sum(t.state == TrialState.COMPLETE for t in s.trials)
    print(f"study {study.name}: {study.evaluator.kind}, {len(study.file.space)} keys, {study.file.sampler}; "
          f"{done}/{trials} complete trials in {url}", file=sys.stderr)
    try:
        optimize(study, s, trials, workers=workers or 1, backend=args.backend, pool=pool,
                 on_trial=_Progress(trials, done))
        print("study: evaluating the base and the best on the held-out set ...", file=sys.stderr)
        summary = finish(study, s, out, url, workers=workers or 1, backend=args.backend, pool=pool)
    except KeyboardInterrupt:
        complete = sum(t.state == TrialState.COMPLETE for t in s.trials)
        print(f"nextage-qp tune: interrupted; {complete} complete trials are in {url}; continue with the same "
              f"command and --resume", file=sys.stderr)
        return 130
    finally:
        if pool is not None:
            pool.close()
            pool.join()
        if started_ray:
            import ray

            ray.shutdown()
    _print(summary, out_console(width=140))
    return 0


def _print(s: dict[str, Any], console: Console) -> None:
    from rich.table import Table

    best = s["best"]
    console.print(f"{s['study']}: best of {s['trials']['complete']} complete trials is trial {best['number']}, "
                  f"value {best['value']:.5g}: {best['line']}", markup=False, soft_wrap=True)
    table = Table(title="base against best (lower objective is better)", title_justify="left")
    for col in ("set", "config", "objective", "outcome"):
        table.add_column(col)
    base = s["base"]
    if base is not None:
        table.add_row("objective's", "base", f"{base['value']:.5g}", base["line"])
    table.add_row("objective's", "best", f"{best['value']:.5g}", best["line"])
    if s["held_out"] is not None:
        for name in ("base", "best"):
            h = s["held_out"][name]
            table.add_row("held-out", name, f"{h['value']:.5g}", h["line"])
    console.print(table)
    console.print(f"tuned config: {s['best_yaml']}; plots: {', '.join(s['plots']) or 'none'}; "
                  f"summary: {Path(s['best_yaml']).parent / 'summary.json'}", markup=False, soft_wrap=True)
    console.print("best values: " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                             for k, v in best["params"].items()), markup=False, soft_wrap=True)
