"""``nextage-qp run CONFIG``: execute a YAML manipulation config and report the final object error."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nextage_qp.commands.common import PLAIN_PROGRESS_S, PLOT_SUFFIXES, SEED, out_console, output_file, print_json
from nextage_qp.errors import ConfigError, one_line
from nextage_qp.io.outputs import refuse_overwriting

if TYPE_CHECKING:
    from rich.console import Console

    from nextage_qp.manipulation.runner import Runner


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``run`` subcommand."""
    p = sub.add_parser("run", help="run a YAML manipulation config (push_cube, dock_dumbbell, ...)")
    p.add_argument("config", help="YAML file, e.g. configs/push_cube.yaml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set scene.poses.cube.pos=[0.35,0.02,0.91] (repeatable)")
    p.add_argument("--seed", type=SEED, default=None,
                   help="jitter object start and target by up to 2 cm and 10 deg with this seed")
    p.add_argument("--robot", metavar="FILE|NAME", help="run the task on this robot (the same as --set robot=...)")
    p.add_argument("--json", action="store_true", help="print one JSON result object on stdout")
    p.add_argument("--log", type=output_file(".npz"), metavar="NPZ",
                   help="write the recorded signals (.npz) and a .json summary")
    p.add_argument("--plot", type=output_file(*PLOT_SUFFIXES), metavar="PNG",
                   help="write a PNG: object distance to target, tool paths, phases")
    p.add_argument("--video", type=output_file(".mp4"), metavar="MP4",
                   help="render an MP4 headless (MUJOCO_GL=egl) with debug markers")
    p.add_argument("--rerun", type=output_file(".rrd"), metavar="RRD",
                   help="write a Rerun recording: the scene in 3-D, joints, torques, tool frames, contact forces, "
                        "phases, estimates (the rerun extra)")
    p.add_argument("--viewer", action="store_true", help="open the MuJoCo viewer with debug markers")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the config; exit 0 on success, 1 when the task failed (outputs are written either way)."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from nextage_qp.manipulation.config import jitter_overrides, load_config
    from nextage_qp.manipulation.runner import Runner

    overrides = [*args.overrides, *([f"robot={args.robot}"] if args.robot else [])]
    overrides = jitter_overrides(args.config, args.seed, overrides) if args.seed is not None else overrides
    if args.log:
        _check_log_summary(args.log)
    cfg = load_config(args.config, overrides)
    refuse_overwriting({"--log": args.log, "--log summary": args.log.with_suffix(".json") if args.log else None,
                        "--plot": args.plot, "--video": args.video, "--rerun": args.rerun},
                       {"the config": args.config, "the robot file": cfg.robot, "the scene": cfg.scene.file})
    runner = Runner(cfg, args.config)
    err = Console(stderr=True)
    callbacks = []
    recorder_video = None
    if args.video:
        from nextage_qp.viz.video import VideoRecorder

        recorder_video = VideoRecorder(runner, args.video)
        callbacks.append(recorder_video.on_tick)
    recording = None
    if args.rerun:
        from nextage_qp.viz.rerun_log import RerunRecording

        recording = RerunRecording(runner, args.rerun)
        callbacks.append(recording.on_tick)
    viewer = None
    if args.viewer:
        from nextage_qp.viz.viewer import LiveViewer

        viewer = LiveViewer(runner)
        callbacks.append(viewer.on_tick)
    # The bar counts phases (how long each takes is not known in advance: timeouts are only upper bounds).
    # Off a terminal (a log, CI), a plain line every PLAIN_PROGRESS_S of wall time instead.
    plain = {"last": time.monotonic()}
    names = [cfg.phase_name(i) for i in range(len(cfg.phases))]
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.fields[phase]}"),
                  TextColumn("sim t={task.fields[t]:.1f} s"), TimeElapsedColumn(), console=err, transient=True,
                  disable=not err.is_terminal) as progress:
        bar = progress.add_task(cfg.task, total=len(names) + 1, phase="", t=0.0)

        def on_tick(r: Runner, phase: Any) -> None:
            if round(r.sim.time / r.sim.ctrl_dt) % 25 == 0:
                done = sum(rec.status == "done" for rec in r.records)
                label = f"{phase.name} ({done + 1}/{len(names)})" if phase is not None else "settle"
                progress.update(bar, completed=done, phase=label, t=r.sim.time)
                if not err.is_terminal and time.monotonic() - plain["last"] >= PLAIN_PROGRESS_S:
                    plain["last"] = time.monotonic()
                    print(f"run {cfg.task}: phase {label}, simulated {r.sim.time:.1f} s", file=sys.stderr,
                          flush=True)
            for cb in callbacks:
                cb(r, phase)

        result = runner.run(on_tick)
    written, failed = _write_outputs(runner, args, recorder_video, recording)
    record = result.as_dict()
    if written:
        record["outputs"] = written
    if failed:
        record["output_errors"] = failed
    if viewer is not None:
        viewer.close()
    if args.json:
        print_json(record)
    else:
        _print_summary(record, out_console())
    camera = ((record.get("estimation") or {}).get("camera") or {})
    if camera.get("dump_error"):  # the frame dump asked for was not written (the run goes on without it)
        print(f"nextage-qp run: warning: {camera['dump_error']}", file=sys.stderr)
    if failed:
        print(f"nextage-qp run: error: {'; '.join(failed)}", file=sys.stderr)
        return 2
    if result.error:
        print(f"nextage-qp run: error: {one_line(result.error)}", file=sys.stderr)
    elif not result.success:  # every phase done, a criterion not met: say which
        print(f"nextage-qp run: failed: {result.unmet_criteria()}", file=sys.stderr)
    return 0 if result.success else 1


def _check_log_summary(log: Path) -> None:
    """Refuse a ``--log`` whose summary (the same name, ``.json``) is a folder or the file standard output goes to.

    Raises:
        ConfigError: Naming the summary's path (``--log run.npz --json > run.json`` would write both into one file).
    """
    summary = log.with_suffix(".json")
    if summary.is_dir():
        raise ConfigError(f"--log {log}: its summary {summary} is a directory; give --log another name")
    try:
        out = os.fstat(sys.stdout.fileno())
        same = summary.exists() and os.path.samestat(out, summary.stat())
    except (OSError, ValueError, AttributeError):  # no real standard output (captured): nothing to clash with
        same = False
    if same:
        raise ConfigError(f"--log {log}: its summary {summary} is the file standard output goes to; give --log "
                          "another name or send the output elsewhere")


def _write_outputs(runner: Runner, args: argparse.Namespace, video: Any,
                   recording: Any = None) -> tuple[dict[str, str], list[str]]:
    """Write every output asked for; one that fails does not stop the others (nor the result)."""
    written: dict[str, str] = {}
    failed: list[str] = []

    def attempt(option: str, path: Path, write: Any) -> None:
        try:
            write()
        except OSError as exc:
            failed.append(f"{option} {path}: cannot write: {exc.strerror or exc}")

    if args.log:
        def log() -> None:
            runner.sim.recorder.meta.update(result=runner.summary())
            written["log_summary"] = str(runner.sim.recorder.save(args.log))
            written["log"] = str(args.log)

        attempt("--log", args.log, log)
    if args.plot:
        from nextage_qp.viz.run import plot_run

        def plot() -> None:
            plot_run(runner, args.plot)
            written["plot"] = str(args.plot)

        attempt("--plot", args.plot, plot)
    if recording is not None:
        def close_recording() -> None:
            recording.close()
            written["rerun"] = str(args.rerun)

        attempt("--rerun", args.rerun, close_recording)
    if video is not None:
        def close_video() -> None:
            video.close()
            written["video"] = str(args.video)

        attempt("--video", args.video, close_video)
    return written, failed


def _judged(result: dict[str, Any]) -> str:
    """The planar error the success criterion judges, against its limit."""
    crit = result.get("criteria", {}).get("object_error", {})
    limit = f" (limit {crit['limit'] * 1e3:g} mm)" if "limit" in crit else ""
    return f"{result['object_error_xy_m'] * 1e3:.2f} mm{limit}"


def _print_summary(result: dict[str, Any], console: Console) -> None:
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=f"{result['task']}: {'SUCCESS' if result['success'] else 'FAILED'}", title_justify="left")
    table.add_column("phase")
    table.add_column("kind")
    table.add_column("status")
    table.add_column(escape("start [s]"), justify="right")
    table.add_column(escape("duration [s]"), justify="right")
    for ph in result["phases"]:
        table.add_row(ph["name"], ph["kind"], ph["status"], f"{ph['start_s']:.2f}", f"{ph['duration_s']:.2f}")
    console.print(table)
    clearance = result["min_obstacle_clearance_m"]
    rows = [
        ("object error (x-y), judged", _judged(result)),
        ("object origin to the target's", f"{result['object_error_m'] * 1e3:.2f} mm (3-D; on a stack, its height)"),
        ("final object position [m]", " ".join(f"{v:.4f}" for v in result["final_object_position"])),
        ("target position [m]", " ".join(f"{v:.4f}" for v in result["target_position"])),
        ("simulated / wall time", f"{result['sim_time_s']:.2f} s / {result['wall_time_s']:.2f} s "
                                  f"(x{result['real_time_factor']:.1f} real time, "
                                  f"{result['physics_share'] * 100:.0f} % of it in the physics)"),
        ("min obstacle clearance", "n/a" if clearance is None else f"{clearance * 1e3:.1f} mm"),
        ("obstacle contacts [steps]", str(result["obstacle_contacts"])),
        ("object dropped", str(result["object_dropped"])),
        ("joint limit violations [steps]", str(result["joint_limit_violations"])),
        ("max |torque|", f"{result['max_abs_torque_nm']:.1f} N m ({result['torque_saturation_ticks']} saturated)"),
    ]
    # markup=False: the unit brackets ("[m]", "[steps]") are text, not rich style tags.
    for key, value in [*rows, *result.get("outputs", {}).items()]:
        console.print(f"  {key:<32} {value}", markup=False)
