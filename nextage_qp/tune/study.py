"""Run a study on Optuna: the validated search space, the storage, the sampler and the trial loop.

Each trial suggests every searched key, runs its evaluation's tasks on a sweep backend (the local process pool,
kept across trials, or Ray) and reports the evaluation's value (lower is better). The study lives in an Optuna
storage (an SQLite file in the output folder unless ``--storage`` names another database), so a study that was
interrupted continues with ``--resume``, and several machines that share one storage share one study: each stops
when the storage holds the requested number of complete trials. A trial whose process was killed is noticed by
its missing heartbeat and run again with the same parameters. On a new study the base values are trial 0.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from nextage_qp.errors import ConfigError, one_line
from nextage_qp.sweep.run import run_sweep
from nextage_qp.tune.evaluate import Evaluator, Score
from nextage_qp.tune.spec import Param, StudyFile, read_study

HEARTBEAT_S = 10
"""Interval of a running trial's heartbeat in the storage [s]; a trial silent for 3 intervals is failed."""


class Study:
    """A study file, validated against the file it tunes.

    Args:
        path: The study YAML.

    Raises:
        ConfigError: Any problem with the study file, its sweep or gains file, or a searched key (one line).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.file: StudyFile = read_study(self.path)
        try:
            self.evaluator = self._evaluator()
            self.base_params = self._check_space()
        except ConfigError as exc:
            text = str(exc)
            raise ConfigError(text if text.startswith(str(self.path)) else f"{self.path}: {text}") from None

    @property
    def name(self) -> str:
        """The study file's stem (the study's name in its storage)."""
        return self.path.stem

    def _evaluator(self) -> Evaluator:
        f, folder = self.file, self.path.parent
        if f.sweep is not None:
            from nextage_qp.tune.sweep_eval import SweepEvaluator

            return SweepEvaluator(f.sweep, f.held_out, folder, f.wall_limit)
        from nextage_qp.tune.steps import StepsEvaluator

        assert f.steps is not None
        return StepsEvaluator(f.steps, f.held_out.amplitude_deg if f.held_out else None, folder)

    def _check_space(self) -> dict[str, Any] | None:
        """Validate every key at its bounds (or choices); the base values, or None if one is unset or outside."""
        base: dict[str, Any] = {}
        complete = True
        for key, param in self.file.space.items():
            values = [self.evaluator.base_value(k) for k in (key, *param.also)]
            if any(v is None for v in values) or not _inside(param, values[0]):
                complete = False
            else:
                base[key] = values[0]
            for value in param.choice if param.choice is not None else param.bounds or ():
                for k in (key, *param.also):
                    try:
                        self.evaluator.check_value(k, value)
                    except ConfigError as exc:
                        raise ConfigError(f"space.{key}: value {value!r} for {k}: {exc}") from None
        return base if complete else None

    def expand(self, params: dict[str, Any]) -> dict[str, Any]:
        """Searched keys and their ``also`` keys, each with its value."""
        out = dict(params)
        for key, param in self.file.space.items():
            out.update({other: params[key] for other in param.also})
        return out


def _inside(param: Param, value: Any) -> bool:
    if param.choice is not None:
        return value in param.choice
    lo, hi = param.bounds or (0.0, 0.0)
    return isinstance(value, (int, float)) and not isinstance(value, bool) and lo <= value <= hi


def suggest(trial: Any, key: str, param: Param) -> Any:
    """Ask ``trial`` for the value of one key."""
    if param.choice is not None:
        return trial.suggest_categorical(key, param.choice)
    lo, hi = param.bounds or (0.0, 0.0)
    if param.integer is not None:
        return trial.suggest_int(key, int(lo), int(hi))
    return trial.suggest_float(key, float(lo), float(hi), log=param.log is not None)


def open_storage(url: str) -> Any:
    """An Optuna RDB storage with heartbeats, retrying a killed trial once with its parameters."""
    import optuna
    from optuna.storages import RDBStorage, RetryHeartbeatStaleTrialCallback

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        try:
            return RDBStorage(url, heartbeat_interval=HEARTBEAT_S, grace_period=3 * HEARTBEAT_S,
                              heartbeat_stale_trial_callback=RetryHeartbeatStaleTrialCallback(max_retry=1))
        except Exception as exc:
            raise ConfigError(f"--storage {url}: cannot open it: {one_line(exc)[:200]}") from None


def sampler(study: Study, n_existing: int) -> Any:
    """TPE (default) or CMA-ES, seeded from the study seed and the trials already in the storage."""
    import optuna

    f = study.file
    seed = f.seed + n_existing
    if f.sampler == "cmaes":  # starts from the middle of the ranges; the base values are trial 0 anyway
        return optuna.samplers.CmaEsSampler(seed=seed, n_startup_trials=f.startup_trials,
                                            warn_independent_sampling=False)
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=f.startup_trials)


def open_study(study: Study, storage: Any, *, resume: bool, where: str) -> Any:
    """Create the Optuna study (base values enqueued as trial 0), or load it with ``resume``.

    Raises:
        ConfigError: The storage already holds the study and ``resume`` is not set.
    """
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    names = optuna.study.get_all_study_names(storage)
    if study.name in names and not resume:
        old = optuna.load_study(study_name=study.name, storage=storage)
        raise ConfigError(f"{where} already holds study {study.name!r} ({len(old.trials)} trials); continue it with "
                          f"--resume, or give another --out/--storage")
    n = len(optuna.load_study(study_name=study.name, storage=storage).trials) if study.name in names else 0
    s = optuna.create_study(study_name=study.name, storage=storage, sampler=sampler(study, n),
                            direction="minimize", load_if_exists=True)
    if n == 0:
        s.set_user_attr("study_file", str(study.path))
        s.set_user_attr("kind", study.evaluator.kind)
        if study.base_params is not None:
            s.enqueue_trial(study.base_params, user_attrs={"base": True})
    return s


def optimize(study: Study, optuna_study: Any, trials: int, *, workers: int, backend: str, pool: Any = None,
             on_trial: Callable[[Any, Score, float], None] | None = None) -> int:
    """Run trials until the storage holds ``trials`` complete ones; returns how many this call completed."""
    import optuna
    from optuna.study import MaxTrialsCallback
    from optuna.trial import TrialState

    ev = study.evaluator
    ran = [0]

    def objective(trial: Any) -> float:
        t0 = time.monotonic()
        params = {key: suggest(trial, key, p) for key, p in study.file.space.items()}
        episodes = run_sweep(ev.tasks(study.expand(params)), store=None, workers=workers, backend=backend,
                             episode_fn=ev.episode_fn, pool=pool)
        score = ev.score(episodes)
        if not math.isfinite(score.value):
            raise ConfigError(f"trial {trial.number}: the evaluation returned {score.value}")
        trial.set_user_attr("line", score.line)
        trial.set_user_attr("details", score.details)
        ran[0] += 1
        if on_trial is not None:
            on_trial(trial, score, time.monotonic() - t0)
        return score.value

    done = sum(t.state == TrialState.COMPLETE for t in optuna_study.trials)
    if done < trials:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            optuna_study.optimize(objective, callbacks=[MaxTrialsCallback(trials, states=(TrialState.COMPLETE,))])
    return ran[0]
