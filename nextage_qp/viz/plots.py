"""Figures of the control loop (matplotlib, Agg backend): step response and Cartesian reach."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def plot_step_response(
    arrays: dict[str, np.ndarray],
    joint_index: int,
    joint: str,
    target: float,
    path: str | Path,
    *,
    title: str = "",
) -> Path:
    """Position with reference and target, velocity and torque of one joint against time (cf. report Fig. 8).

    Args:
        arrays: A :class:`~nextage_qp.loop.simulation.Recorder`'s arrays (``t``, ``q``, ``q_ref``, ``qd``, ``tau``).
        joint_index: Index of the joint in the q vector.
        joint: Joint name (labels).
        target: Step target [rad].
        path: PNG to write.
        title: Figure title.
    """
    t, j = arrays["t"], joint_index
    fig, ax = plt.subplots(3, 1, figsize=(8, 7), sharex=True, constrained_layout=True)
    ax[0].plot(t, arrays["q"][:, j], label="q", lw=1.8)
    ax[0].plot(t, arrays["q_ref"][:, j], "--", label="q_ref", lw=1.2)
    ax[0].axhline(target, color="k", lw=0.8, ls=":", label="target")
    band = 0.02 * abs(target - arrays["q"][0, j])
    ax[0].axhspan(target - band, target + band, color="0.85", label="2 % band")
    ax[0].set_ylabel(f"{joint} [rad]")
    ax[1].plot(t, arrays["qd"][:, j], label="q̇", lw=1.5)
    ax[1].plot(t, arrays["qd_ref"][:, j], "--", label="q̇_ref", lw=1.2)
    ax[1].set_ylabel("velocity [rad/s]")
    ax[2].plot(t, arrays["tau"][:, j], color="C3", lw=1.5, label="torque")
    ax[2].set_ylabel("torque [N·m]")
    ax[2].set_xlabel("time [s]")
    for a in ax:
        a.grid(alpha=0.3)
        a.legend(loc="best", fontsize=8)
    ax[0].set_title(title or f"{joint}: step to {target:.3f} rad")
    return _save(fig, path)


def plot_reach(
    t: np.ndarray,
    distance: np.ndarray,
    path: str | Path,
    *,
    frame: str,
    tau: np.ndarray | None = None,
    title: str = "",
) -> Path:
    """Distance of a frame to its Cartesian target against time (log scale), with the 1 mm and 2 mm lines.

    Args:
        t: Time [s], (k,).
        distance: ‖p_frame − p_target‖ [m], (k,).
        path: PNG to write.
        frame: Frame name (labels).
        tau: Optional joint torques [N·m], (k, n), shown as the largest magnitude per step.
        title: Figure title.
    """
    rows = 2 if tau is not None else 1
    fig, ax = plt.subplots(rows, 1, figsize=(8, 3.2 * rows + 0.5), sharex=True, constrained_layout=True, squeeze=False)
    a = ax[0, 0]
    a.semilogy(t, np.maximum(distance * 1e3, 1e-3), lw=1.8, label=f"‖{frame} − target‖")
    for level, style in ((2.0, "--"), (1.0, ":")):
        a.axhline(level, color="k", lw=0.8, ls=style, label=f"{level:g} mm")
    a.set_ylabel("distance to target [mm]")
    a.grid(alpha=0.3, which="both")
    a.legend(loc="best", fontsize=8)
    a.set_title(title or f"reach: {frame}")
    if tau is not None:
        b = ax[1, 0]
        b.plot(t, np.abs(tau).max(axis=1), color="C3", lw=1.2)
        b.set_ylabel("max |torque| [N·m]")
        b.grid(alpha=0.3)
    ax[-1, 0].set_xlabel("time [s]")
    return _save(fig, path)


def _save(fig: plt.Figure, path: str | Path) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def plot_bimanual(arrays: dict[str, np.ndarray], frames: tuple[str, str], path: str | Path, *, title: str = "") -> Path:
    """The coupled frame's deviation from its start pose relative to the leading frame, against time.

    Args:
        arrays: A recorder's arrays with ``frame_<lead>`` and ``frame_<follow>`` (k, 7).
        frames: (lead, follow).
        path: PNG to write.
        title: Figure title.
    """
    import mujoco

    lead, follow = arrays[f"frame_{frames[0]}"], arrays[f"frame_{frames[1]}"]
    rel = np.empty((len(lead), 3))
    mat = np.empty(9)
    for k in range(len(lead)):
        mujoco.mju_quat2Mat(mat, lead[k, 3:])
        rel[k] = mat.reshape(3, 3).T @ (follow[k, :3] - lead[k, :3])
    err = np.linalg.norm(rel - rel[0], axis=1) * 1e3
    moved = np.linalg.norm(lead[:, :3] - lead[0, :3], axis=1) * 1e3
    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    ax[0].plot(arrays["t"], moved, lw=1.8, label=f"{frames[0]} travelled")
    ax[0].set_ylabel("travel [mm]")
    ax[1].plot(arrays["t"], err, lw=1.8, color="C1", label=f"{frames[1]} relative to {frames[0]}: error")
    ax[1].axhline(2.0, color="k", lw=0.8, ls="--", label="2 mm")
    ax[1].set_ylabel("relative error [mm]")
    ax[1].set_xlabel("time [s]")
    for a in ax:
        a.grid(alpha=0.3)
        a.legend(loc="best", fontsize=8)
    ax[0].set_title(title or "bimanual move")
    return _save(fig, path)
