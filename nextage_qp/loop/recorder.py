"""The log of a simulated run: every control tick's joint state, reference, torque and chosen poses.

Saved as ``.npz`` (arrays) plus a ``.json`` summary (duration, peak torques and tracking errors, final state).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from nextage_qp.geometry import mats_to_quats
from nextage_qp.io.json_out import dumps


class Recorder:
    """Per-control-tick log of the loop, growing in chunks; saved as ``.npz`` plus a ``.json`` summary.

    Arrays in the ``.npz``: ``t`` [s] (k,), ``q``, ``qd``, ``q_ref``, ``qd_ref`` [rad, rad/s] and ``tau``
    [N·m] (k, 15), ``frame_<name>`` and ``object_<name>`` (k, 7: position [m], quaternion w x y z), and for
    every signal added with :meth:`add` ``extra_<name>`` (m, ...) with its times ``extra_<name>_t``. Saved files
    also hold ``joint_names`` (the column order of the (k, 15) arrays), ``frame_names`` and ``object_names``.

    Attributes:
        meta: Free-form facts merged into the JSON summary (e.g. ``error``, the target).
    """

    def __init__(
        self,
        joint_names: Sequence[str],
        frames: Sequence[str],
        objects: Sequence[str],
        *,
        sim_dt: float,
        ctrl_dt: float,
    ) -> None:
        self.joint_names = tuple(joint_names)
        n = len(self.joint_names)
        self.frames, self.objects = tuple(frames), tuple(objects)
        self._dims = {"t": 1, "q": n, "qd": n, "q_ref": n, "qd_ref": n, "tau": n}
        # Frames are stored as they come from MuJoCo (position and rotation matrix, 12 values each) and turned
        # into position + quaternion only when the arrays are read: no conversion inside the physics loop.
        self._dims |= {"frames": 12 * len(self.frames)} | {f"object_{o}": 7 for o in self.objects}
        self._timing = {"sim_dt": sim_dt, "ctrl_dt": ctrl_dt}
        self.clear()

    def clear(self) -> None:
        """Drop everything recorded."""
        self._n = 0
        self._buf = {k: np.empty((4096, dim)) for k, dim in self._dims.items()}
        self._extra: dict[str, tuple[list[float], list[Any]]] = {}
        self.meta: dict[str, Any] = {}

    def __len__(self) -> int:
        return self._n

    def record(self, t: float, *rows: Any) -> None:
        """Append one step: time, q, qd, q_ref, qd_ref, tau (None: set later), frame poses, object poses.

        The frame poses are one array (n_frames, 12): position [m] and row-major rotation matrix per frame.
        """
        if self._n == len(self._buf["t"]):
            self._buf = {k: np.concatenate([b, np.empty_like(b)]) for k, b in self._buf.items()}
        i, buf = self._n, self._buf
        buf["t"][i, 0] = t
        for key, row in zip(("q", "qd", "q_ref", "qd_ref", "tau"), rows[:5], strict=True):
            if row is not None:
                buf[key][i] = row
        buf["frames"][i] = rows[5].ravel()
        for name, pose in zip(self.objects, rows[6], strict=True):
            buf[f"object_{name}"][i] = pose
        self._n += 1

    def set_last(self, key: str, row: Any) -> None:
        """Overwrite one array's row of the last step (e.g. ``tau``, known only once the step has run)."""
        self._buf[key][self._n - 1] = row

    def add(self, name: str, t: float, value: Any) -> None:
        """Append an extra signal sample (e.g. from a hook): ``extra_<name>`` at time ``t`` [s]."""
        ts, values = self._extra.setdefault(name, ([], []))
        ts.append(t)
        values.append(np.asarray(value, dtype=float))

    def recent(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The last ``n`` rows' time [s], q [rad] and qd [rad/s] (views, no copy)."""
        lo = max(0, self._n - n)
        b = self._buf
        return b["t"][lo : self._n, 0], b["q"][lo : self._n], b["qd"][lo : self._n]

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything recorded so far, as arrays (``t`` is 1-D)."""
        out = {k: b[: self._n].copy() for k, b in self._buf.items() if k != "frames"}
        out["t"] = out["t"][:, 0]
        raw = self._buf["frames"][: self._n].reshape(self._n, len(self.frames), 12)
        for j, name in enumerate(self.frames):
            out[f"frame_{name}"] = np.concatenate([raw[:, j, :3], mats_to_quats(raw[:, j, 3:])], axis=1)
        for name, (ts, values) in self._extra.items():
            out[f"extra_{name}"], out[f"extra_{name}_t"] = np.asarray(values), np.asarray(ts)
        return out

    def summary(self) -> dict[str, Any]:
        """Key figures of the run: duration, peak torques, peak tracking errors, final state, plus ``meta``."""
        a, names = self.arrays(), self.joint_names
        out: dict[str, Any] = {"samples": self._n, **self._timing, "frames": list(self.frames)}
        if self._n:
            err = np.abs(a["q_ref"] - a["q"])
            out |= {
                "duration_s": float(a["t"][-1] + self._timing["sim_dt"]),
                "max_abs_torque_nm": dict(zip(names, np.abs(a["tau"]).max(0).round(4).tolist(), strict=True)),
                "max_tracking_error_rad": dict(zip(names, err.max(0).round(6).tolist(), strict=True)),
                "final_q": dict(zip(names, a["q"][-1].round(6).tolist(), strict=True)),
                "final_frames": {f: a[f"frame_{f}"][-1].round(6).tolist() for f in self.frames},
                "final_objects": {o: a[f"object_{o}"][-1].round(6).tolist() for o in self.objects},
            }
        return out | self.meta

    def save(self, npz_path: str | Path) -> Path:
        """Write ``npz_path`` (arrays) and the same name with ``.json`` (summary); returns the JSON path."""
        path = Path(npz_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        savez: Any = np.savez_compressed  # numpy's stub mistypes **arrays
        names = {"joint_names": np.array(self.joint_names), "frame_names": np.array(self.frames, dtype=str),
                 "object_names": np.array(self.objects, dtype=str)}
        savez(path, **self.arrays(), **names)
        js = path.with_suffix(".json")
        js.write_text(dumps(self.summary()) + "\n")
        return js


class FrameRows:
    """Reads the world poses of sites and bodies as one (n_frames, 12) array (a reused buffer).

    Args:
        frames: ``(kind, id)`` pairs, kind ``"site"`` or ``"body"``.
        data: The MuJoCo state to read.
    """

    def __init__(self, frames: Sequence[tuple[str, int]], data: Any) -> None:
        self.data, self._out = data, np.zeros((len(frames), 12))
        self._site_rows = np.array([i for i, (k, _) in enumerate(frames) if k == "site"], dtype=int)
        self._site_ids = np.array([fid for k, fid in frames if k == "site"], dtype=int)
        self._body_rows = np.array([i for i, (k, _) in enumerate(frames) if k != "site"], dtype=int)
        self._body_ids = np.array([fid for k, fid in frames if k != "site"], dtype=int)

    def __call__(self) -> np.ndarray:
        """Position and row-major rotation matrix of every frame, (n_frames, 12)."""
        d, out = self.data, self._out
        if self._site_ids.size:
            out[self._site_rows, :3] = d.site_xpos[self._site_ids]
            out[self._site_rows, 3:] = d.site_xmat[self._site_ids]
        if self._body_ids.size:
            out[self._body_rows, :3] = d.xpos[self._body_ids]
            out[self._body_rows, 3:] = d.xmat[self._body_ids]
        return out


class StageTimer:
    """Wall time of each stage of :meth:`Simulation.tick` (set ``sim.timer`` to measure; None costs nothing)."""

    def __init__(self) -> None:
        self.samples: dict[str, list[float]] = {}
        self._t = time.perf_counter()

    def start(self) -> None:
        """Mark the start of the next stage."""
        self._t = time.perf_counter()

    def lap(self, stage: str) -> None:
        """Charge the time since the last mark to ``stage`` and mark again."""
        now = time.perf_counter()
        self.samples.setdefault(stage, []).append(now - self._t)
        self._t = now
