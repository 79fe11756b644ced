"""A sweep's directory: ``sweep.json`` (what was run) and ``episodes.jsonl`` (one finished episode per line).

Each episode is appended and flushed to disk the moment it finishes, so Ctrl-C, a dead worker or a killed
machine loses only the episodes that were running; ``--resume`` reads the file back and runs the rest.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from nextage_qp.errors import ConfigError
from nextage_qp.sweep.episode import Episode
from nextage_qp.sweep.spec import SweepSpec


def fingerprint(spec: SweepSpec) -> str:
    """SHA-256 of the sweep file, its base config and the command's ``--set`` (a resumed sweep runs the same)."""
    digest = hashlib.sha256()
    for path in (spec.path, spec.base_path):
        digest.update(path.read_bytes())
    for item in spec.extra:
        digest.update(item.encode())
    return digest.hexdigest()


def default_folder(spec: SweepSpec, seed: int) -> Path:
    """Where a sweep keeps its records unless told otherwise: ``runs/sweeps/NAME-seedS``."""
    return Path("runs") / "sweeps" / f"{spec.name}-seed{seed}"


class SweepStore:
    """The output directory of one sweep (file + seed).

    Args:
        out: Directory (created when missing).
        spec: The sweep.
        seed: The sweep seed.
        resume: Continue the episodes already on disk; without it a directory that holds episodes is an error.

    Raises:
        ConfigError: The directory cannot be written, holds another sweep, or holds episodes without ``resume``.
    """

    def __init__(self, out: Path, spec: SweepSpec, seed: int, *, resume: bool) -> None:
        self.out = out
        self.header = {"sweep": str(spec.path), "base": str(spec.base_path), "set": spec.extra, "seed": seed,
                       "fingerprint": fingerprint(spec)}
        self.episodes_path = out / "episodes.jsonl"
        self.done: dict[int, Episode] = {}
        self.lost: dict[int, Episode] = {}
        """Episodes on disk whose process died (``--resume`` runs them again), by index."""
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"--out {out}: cannot create the directory ({exc.strerror})") from None
        header_path = out / "sweep.json"
        records = self.episodes_path.is_file() and self.episodes_path.stat().st_size > 0
        if header_path.exists():
            old = _header(out, header_path)
            if not resume and records:
                raise ConfigError(f"--out {out}: already holds episodes of a sweep; pass --resume to continue it, "
                                  "or choose another --out")
            mismatch = [k for k in ("seed", "fingerprint") if old.get(k) != self.header[k]]
            if resume and mismatch:
                raise ConfigError(f"--resume: {out} holds a sweep with another {' and '.join(mismatch)} "
                                  f"(seed {old.get('seed')}, sweep {old.get('sweep')}); it cannot be continued")
        elif records:  # episodes without the header that says which sweep they belong to: never overwritten
            raise ConfigError(f"--out {out}: holds {self.episodes_path} but no sweep.json, so it cannot be verified "
                              "to be this sweep's; choose another --out, or remove the file")
        if resume:  # a lost episode (its process died) runs again
            kept = self._read()
            self.done = {i: e for i, e in kept.items() if e.status != "lost"}
            self.lost = {i: e for i, e in kept.items() if e.status == "lost"}
        try:
            if not resume and self.episodes_path.exists():
                self.episodes_path.unlink()
            header_path.write_text(json.dumps(self.header, indent=2) + "\n")
            self._file = self.episodes_path.open("a")
        except OSError as exc:
            raise ConfigError(f"--out {out}: cannot write ({exc.strerror})") from None

    def _read(self) -> dict[int, Episode]:
        done: dict[int, Episode] = {}
        if not self.episodes_path.is_file():
            return done
        try:
            data = self.episodes_path.read_bytes()
            if data and not data.endswith(b"\n"):  # the last line was cut short by an interruption: it runs again
                data = data[: data.rfind(b"\n") + 1]
                self.episodes_path.write_bytes(data)
        except OSError as exc:
            raise ConfigError(f"--resume: cannot read or mend {self.episodes_path} ({exc.strerror or exc})") from None
        for line in data.splitlines():
            try:  # a line that is not a record (not UTF-8, not JSON, not an episode) runs again
                ep = Episode.from_json(json.loads(line.decode("utf-8")))
            except (UnicodeDecodeError, json.JSONDecodeError, TypeError, KeyError, ValueError, AttributeError):
                continue
            done[ep.index] = ep
        return done

    def add(self, episode: Episode) -> None:
        """Append one finished episode and flush it to disk (a later record of the same index replaces it)."""
        self.done[episode.index] = episode
        try:
            self._file.write(json.dumps(episode.to_json(), default=_plain) + "\n")
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as exc:  # a full disk: the episodes kept so far stay, --resume goes on from them
            raise ConfigError(f"--out {self.out}: cannot write episode {episode.index}'s record "
                              f"({exc.strerror or exc}); free space and run again with --resume") from None

    def close(self) -> None:
        """Close the episodes file."""
        self._file.close()


def _header(out: Path, path: Path) -> dict[str, Any]:
    """The ``sweep.json`` of an earlier run; a file this tool did not write is refused, and left as it is."""
    try:
        doc = json.loads(path.read_text())
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot read {path} ({exc.strerror or exc})") from None
    except ValueError:  # not JSON, or not UTF-8
        doc = None
    if not isinstance(doc, dict) or not {"seed", "fingerprint"} <= doc.keys():
        raise ConfigError(f"--out {out}: {path} is not a sweep record this tool wrote (a JSON object with the "
                          "sweep's seed and fingerprint); choose another --out, or remove the file")
    return doc


def _plain(x: Any) -> Any:
    if hasattr(x, "tolist"):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
