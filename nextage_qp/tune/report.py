"""The end of a study: the best trial checked against the base on the held-out set, the tuned YAML, the summary."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

from nextage_qp.sweep.run import run_sweep
from nextage_qp.tune.evaluate import Score, dump_yaml
from nextage_qp.tune.study import Study


def evaluate(study: Study, params: dict[str, Any], *, held_out: bool, workers: int, backend: str,
             pool: Any = None) -> Score | None:
    """Score ``params`` (expanded to their ``also`` keys) on the objective's or the held-out set."""
    ev = study.evaluator
    tasks = ev.tasks(study.expand(params) if params else {}, held_out=held_out)
    if not tasks:
        return None
    return ev.score(run_sweep(tasks, store=None, workers=workers, backend=backend, episode_fn=ev.episode_fn,
                              pool=pool))


def _trial_doc(trial: Any) -> dict[str, Any]:
    return {"number": trial.number, "value": trial.value, "params": trial.params,
            "line": trial.user_attrs.get("line"), "details": trial.user_attrs.get("details")}


def _score_doc(score: Score | None) -> dict[str, Any] | None:
    return None if score is None else {"value": score.value, "line": score.line, "details": score.details}


def finish(study: Study, s: Any, out: Path, storage_url: str, *, workers: int, backend: str,
           pool: Any = None) -> dict[str, Any]:
    """Evaluate best and base on the held-out set, write ``best.yaml``, ``summary.json`` and the plots."""
    from optuna.trial import TrialState

    from nextage_qp.io.json_out import dumps
    from nextage_qp.viz.tune import plot_history, plot_importances

    complete = [t for t in s.trials if t.state == TrialState.COMPLETE]
    best = s.best_trial
    base_trial = next((t for t in complete if t.user_attrs.get("base")), None)
    base_score = None if base_trial is not None else evaluate(study, {}, held_out=False, workers=workers,
                                                              backend=backend, pool=pool)
    held_base = evaluate(study, {}, held_out=True, workers=workers, backend=backend, pool=pool)
    held_best = evaluate(study, best.params, held_out=True, workers=workers, backend=backend, pool=pool)
    states = {state.name.lower(): sum(t.state == state for t in s.trials) for state in TrialState}
    summary: dict[str, Any] = {
        "study": study.name, "study_file": str(study.path), "kind": study.evaluator.kind,
        "storage": storage_url, "sampler": study.file.sampler, "trials": states,
        "space": {k: {"kind": p.kind, "bounds": p.bounds, "choice": p.choice, "also": p.also}
                  for k, p in study.file.space.items()},
        "best": _trial_doc(best),
        "base": _trial_doc(base_trial) if base_trial is not None else _score_doc(base_score),
        "held_out": None if held_best is None else {"base": _score_doc(held_base), "best": _score_doc(held_best)},
        "skipped_steps": getattr(study.evaluator, "skipped", None),
        "history": [{"number": t.number, "value": t.value, "params": t.params} for t in complete],
    }
    out.mkdir(parents=True, exist_ok=True)
    tuned = study.expand(best.params)
    held = ("" if held_best is None or held_base is None
            else f"\nheld-out set: base {held_base.line}\n              best {held_best.line}")
    header = (f"Tuned by: nextage-qp tune {study.path} (study {study.name!r}, {study.file.sampler}, "
              f"{states['complete']} complete trials)\nbest trial {best.number}: value {best.value:.6g}; "
              f"{best.user_attrs.get('line')}" + held + "\n"
              + textwrap.fill("tuned keys: " + ", ".join(sorted(tuned)), 112))
    (out / "best.yaml").write_text(dump_yaml(study.evaluator.tuned_doc(tuned, out), header))
    summary["best_yaml"] = str(out / "best.yaml")
    summary["plots"] = [str(p) for p in (plot_history(summary, out / "history.png"),
                                         plot_importances(s, out / "importance.png")) if p is not None]
    (out / "summary.json").write_text(dumps(summary) + "\n")
    return summary
