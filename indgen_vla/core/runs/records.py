"""Run directories: the manifest, append-safe ``episodes.parquet`` and the resume API (docs/contracts.md)."""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import RunDirError
from indgen_vla.core.runs.redact import redact, redact_tree

MANIFEST = "manifest.json"
EPISODES = "episodes.parquet"
SUMMARY = "summary.json"
REPORT = "report.md"
SECTIONS = "report.d"  # extra report.md sections other tools keep in the run dir (*.md, appended)

COLUMNS = (
    "run_id", "policy", "data_regime", "scene", "task", "axis", "level", "param",
    "episode", "seed", "success", "steps", "status", "error", "wall_s", "video", "failure", "progress",
    "shared_from",
)  # fmt: skip
# columns added after the first release: older run dirs read with this default (progress: missing, never 0)
OPTIONAL = {"failure": "", "progress": None, "shared_from": ""}
KEY = ("task", "axis", "level", "episode")
# episodes.parquet is rewritten whole per append up to FLUSH_EVERY_ROWS rows; past that (the cost grows with the
# run: 150 ms CPU per rewrite at 20,000 rows) at most FLUSH_SHARE of the wall time goes into rewriting it, so a
# long run's coordinator is not spent on Parquet (docs/results/benchmarks/gpu.md, issue 28). Every appended row first goes to
# JOURNAL (one JSON line, O(1)), which a flush empties: a SIGKILL between rewrites loses no finished episode.
FLUSH_EVERY_ROWS = 256
FLUSH_SHARE = 0.05
JOURNAL = ".episodes.journal"


# an episode's status: "ok" finished (success or failure), "error" a fault a re-run retries, "unavailable" its initial
# state cannot hold the level (a placement check or pick window rules the seed out: never retried, out of n)
STATUSES = ("ok", "error", "unavailable")
FINISHED = ("ok", "unavailable")  # statuses a resume does not run again


@dataclass(frozen=True)
class EpisodeRecord:
    """One finished episode, exactly one row of ``episodes.parquet``."""

    run_id: str
    policy: str
    data_regime: str
    scene: str
    task: str
    axis: str
    level: int
    param: float
    episode: int
    seed: int
    success: bool
    steps: int
    status: str = "ok"
    error: str = ""
    wall_s: float = 0.0
    video: str = ""
    # scenes.failure mode ("none" on success, "error"/"unavailable" for such rows; "" = not classified)
    failure: str = ""
    # scenes.failure progress 0..5 (indgen_vla.core.reporting.partial_credit.STAGES); None = not scored (stored as missing, never 0)
    progress: int | None = None
    # "" = rolled out for its own axis; else the axis whose level-0 rollout this row copies (T0 run once, plan.shared)
    shared_from: str = ""

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"episode status must be one of {', '.join(STATUSES)}, got {self.status!r}")
        if self.progress is not None and (isinstance(self.progress, bool) or self.progress not in range(6)):
            raise ValueError(f"episode progress must be an integer 0..5 or None, got {self.progress!r}")

    @property
    def key(self) -> tuple[str, str, int, int]:
        return (self.task, self.axis, int(self.level), int(self.episode))


assert tuple(f.name for f in fields(EpisodeRecord)) == COLUMNS


def _umask() -> int:
    """The process's umask (read without changing it where /proc allows; os.umask is process-wide)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write to a temp file in the same directory, fsync, then rename over ``path``. The file gets the mode a
    plain ``open(path, "w")`` would (0o666 less the umask), not mkstemp's owner-only 0o600, so a run directory
    stays readable by the group and others as the user's umask intends."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), 0o666 & ~_umask())
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def atomic_write_json(path: Path, obj: Any) -> None:
    atomic_write_bytes(Path(path), (json.dumps(obj, indent=2, sort_keys=False, default=str) + "\n").encode())


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(Path(path), text.encode())


def atomic_savefig(fig, path: Path) -> None:
    """``fig.savefig(path)`` through a temp file and a rename: two reports written at once (``indgen report``
    while ``indgen real record`` completes a run) never leave a half-written plot."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format=Path(path).suffix.lstrip(".") or "png")
    atomic_write_bytes(Path(path), buf.getvalue())


def write_result(out: Path, stem: str, data: Any, markdown: str) -> None:
    """``out/<stem>.json`` and ``out/<stem>.md`` of an analysis command, atomically; one clear line if ``out``
    cannot be written."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise RunDirError(f"cannot write to --out {out}: {e.strerror}; choose another directory") from None
    atomic_write_json(out / f"{stem}.json", data)
    atomic_write_text(out / f"{stem}.md", markdown)


def _schema():
    import pyarrow as pa

    return pa.schema([
        ("run_id", pa.string()), ("policy", pa.string()), ("data_regime", pa.string()),
        ("scene", pa.string()), ("task", pa.string()), ("axis", pa.string()),
        ("level", pa.int64()), ("param", pa.float64()), ("episode", pa.int64()), ("seed", pa.int64()),
        ("success", pa.bool_()), ("steps", pa.int64()), ("status", pa.string()), ("error", pa.string()),
        ("wall_s", pa.float64()), ("video", pa.string()), ("failure", pa.string()), ("progress", pa.int8()),
        ("shared_from", pa.string()),
    ])  # fmt: skip


class RunDir:
    """A run directory; every write is atomic, so a SIGKILL never corrupts what was already written.

    ``episodes.parquet`` is rewritten whole through a temp file and ``os.replace`` after each append while a
    run has up to ``FLUSH_EVERY_ROWS`` rows, later at most every ``cost / FLUSH_SHARE`` seconds, and by ``flush()``
    (``evaluate`` calls it when its episodes end or stop): readers always see a complete Parquet file with one
    row per finished episode. Each append is first written to ``JOURNAL`` (one JSON line per row) and every
    rewrite empties it, so a run SIGKILLed between rewrites resumes with every finished episode: ``RunDir``
    replays the journal over the Parquet rows in order (the last line of a key wins; a torn last line is the
    write the kill interrupted and is dropped).
    """

    def __init__(self, path: str | os.PathLike[str]):
        self.path = Path(path)
        self._rows: dict[tuple[str, str, int, int], dict[str, Any]] | None = None
        self._table = None  # episodes.parquet as read by a reader that never appended (``episodes``)
        self._pending = False  # rows appended but not yet in episodes.parquet
        self._flush_cost, self._flushed_at = 0.0, 0.0

    # ----------------------------------------------------------------- creation / opening
    @classmethod
    def create_or_resume(cls, path: str | os.PathLike[str], manifest: Mapping[str, Any]) -> RunDir:
        """Start a new run, or resume one whose manifest has the same ``plan``; refuse a different plan. Secrets in
        the policy spec are masked (``redact``) before anything is compared or written."""
        manifest = redact_tree(dict(manifest))
        run = cls(path)
        try:
            run.path.mkdir(parents=True, exist_ok=True)
            probe = run.path / ".write_probe"
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as e:
            raise RunDirError(
                f"cannot write to output directory {run.path}: {e.strerror}; choose another --out"
            ) from None
        for stale in run.path.glob(".*.parquet.*"):  # temp files of a writer killed mid-write
            stale.unlink(missing_ok=True)
        for stale in run.path.glob(".*.json.*"):
            stale.unlink(missing_ok=True)
        journal = run.path / JOURNAL
        if journal.exists():  # a write a kill cut short ends without a newline: drop it before appending more
            data = journal.read_bytes()
            if data and not data.endswith(b"\n"):
                os.truncate(journal, data.rfind(b"\n") + 1)
        mpath = run.path / MANIFEST
        if mpath.exists():
            old = run.manifest
            old_plan = redact_tree(
                old.get("plan", {})
            )  # a run recorded before secrets were masked resumes too
            if old_plan != manifest.get("plan", {}):
                diff = sorted(
                    k
                    for k in set(old_plan) | set(manifest.get("plan", {}))
                    if old_plan.get(k) != manifest.get("plan", {}).get(k)
                )
                raise RunDirError(
                    f"{run.path} holds a run with a different plan (differs in: {', '.join(diff) or 'plan'}"
                    f"{_first_difference(diff, old_plan, manifest.get('plan', {}))}); " + _resume_hint(old)
                )
        elif (run.path / EPISODES).exists() or journal.exists():  # rows no plan vouches for: never mixed in
            raise RunDirError(
                f"{run.path} holds episodes but no {MANIFEST}, so which run made them is unknown; "
                f"restore its {MANIFEST} or use a new --out"
            )
        else:
            atomic_write_json(mpath, dict(manifest))
        return run

    @classmethod
    def open(cls, path: str | os.PathLike[str]) -> RunDir:
        """Open an existing run for reading; raise ``RunDirError`` if it is missing or corrupt."""
        run = cls(path)
        if not run.path.is_dir():
            raise RunDirError(
                f"run directory {run.path} does not exist; pass the --out of an 'indgen evaluate' run"
            )
        if not (run.path / MANIFEST).exists():
            inner = sorted(str(m.parent) for m in run.path.glob(f"*/{MANIFEST}"))
            fix = (f"; pass the runs in it instead: {' '.join(inner[:4])}{' ...' * (len(inner) > 4)}" if inner
                   else "; pass the --out of an 'indgen evaluate' run")  # fmt: skip
            raise RunDirError(
                f"{run.path} has no {MANIFEST}; it is not a run directory written by 'indgen evaluate'{fix}"
            )
        run.manifest  # noqa: B018 - validates the JSON
        run.episodes()
        return run

    @property
    def manifest(self) -> dict[str, Any]:
        try:
            data = json.loads((self.path / MANIFEST).read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise RunDirError(
                f"{self.path / MANIFEST} is unreadable or corrupt ({e}); re-run evaluate into a new --out"
            ) from None
        if not isinstance(data, dict):
            raise RunDirError(
                f"{self.path / MANIFEST} is not a JSON object; re-run evaluate into a new --out"
            )
        return data

    # ----------------------------------------------------------------- episodes
    def _load(self) -> dict[tuple[str, str, int, int], dict[str, Any]]:
        if self._rows is None:
            table = self._read_table() if self._table is None else self._table  # the file as first read
            # from here on the rows are this object's own (appends, journal)
            self._rows, self._table = {}, None
            if table is not None:
                for row in table.to_pylist():
                    self._keep(row)
            self._replay_journal()
        return self._rows

    def _read_table(self):
        """episodes.parquet's COLUMNS (those it has) as an Arrow table; None when there is no file."""
        p = self.path / EPISODES
        if not p.exists():
            return None
        import pyarrow.parquet as pq

        try:  # one open file: a path read can stat the old file and open the new one a rewrite just put there
            with open(p, "rb") as f:
                table = pq.read_table(f)
        except Exception as e:  # pyarrow raises several types for a damaged file
            raise RunDirError(
                f"{p} is corrupt ({type(e).__name__}); move it away to restart the run"
            ) from None
        missing = set(COLUMNS) - set(table.column_names) - set(OPTIONAL)
        if missing:
            raise RunDirError(f"{p} lacks columns {sorted(missing)}; it was not written by indgen")
        return table.select([c for c in COLUMNS if c in table.column_names])

    def _stored_frame(self):
        """The episodes straight from the Parquet table when they are exactly its rows (nothing appended, no journal
        to replay, one row per key, at least one row), else None: a reader skips building one dict per row. The
        table is read once, like the rows ``_load`` keeps: later calls see the same episodes."""
        if self._rows is not None:
            return None
        if self._table is None:
            if (self.path / JOURNAL).exists():
                return None
            self._table = self._read_table()
        if self._table is None or self._table.num_rows == 0:
            return None
        df = self._table.to_pandas()
        if df.duplicated(list(KEY)).any():  # the dicts keep the last row of a key at its first one's place
            return None
        for column, default in OPTIONAL.items():
            if column not in df:
                df[column] = default
        return df[list(COLUMNS)]

    def _keep(self, row: dict[str, Any]) -> None:
        """A stored row under its key (rows written before an OPTIONAL column existed get its default)."""
        row = {**OPTIONAL, **row}
        self._rows[(row["task"], row["axis"], int(row["level"]), int(row["episode"]))] = row

    def _replay_journal(self) -> None:
        """Rows appended after the last rewrite of episodes.parquet (a run killed before its next rewrite)."""
        journal = self.path / JOURNAL
        if not journal.exists():
            return
        replayed = False
        for line in journal.read_bytes().splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue  # the line a kill cut short (create_or_resume trims it): never reported finished
            self._keep({c: row[c] for c in COLUMNS if c in row})
            replayed = True
        self._pending = replayed

    def _journal(self, rows: list[dict[str, Any]]) -> None:
        """Append rows to the journal in one write (O(1) per episode, unlike a Parquet rewrite)."""
        data = b"".join(json.dumps(r, separators=(",", ":")).encode() + b"\n" for r in rows)
        fd = os.open(self.path / JOURNAL, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        try:
            os.write(fd, data)
        finally:
            os.close(fd)

    def rows(self) -> list[dict[str, Any]]:
        """Every recorded episode as a dict of ``COLUMNS`` (journal replayed), e.g. to write them into another run."""
        return [dict(r) for r in self._load().values()]

    def done_keys(self, include_errors: bool = False) -> set[tuple[str, str, int, int]]:
        """Keys ``(task, axis, level, episode)`` already finished (``ok`` or ``unavailable``, which its seed decides);
        error rows are retried unless asked."""
        return {k for k, r in self._load().items() if include_errors or r["status"] in FINISHED}

    def append(self, records: Iterable[EpisodeRecord]) -> None:
        """Add finished episodes (an error row for the same key is replaced) and persist atomically."""
        rows = self._load()
        new = list(records)
        if not new:
            return
        for rec in new:
            old = rows.get(rec.key)
            if old is not None and old["status"] in FINISHED:
                raise RunDirError(
                    f"episode {rec.key} is already recorded in {self.path}; refusing to duplicate it"
                )
            rows[rec.key] = _row(rec)
        self._journal([rows[rec.key] for rec in new])
        self._pending = True
        if (
            len(rows) <= FLUSH_EVERY_ROWS
            or time.monotonic() - self._flushed_at >= self._flush_cost / FLUSH_SHARE
        ):
            self._flush()

    def flush(self) -> None:
        """Write the appended rows that ``append`` deferred (a no-op when there are none)."""
        if self._pending:
            self._flush()

    def update_manifest(self, **fields: Any) -> None:
        """Add top-level fields to manifest.json (atomic); the ``plan`` a resume matches is never changed here."""
        if "plan" in fields:
            raise RunDirError("the manifest's plan is fixed when the run is created")
        atomic_write_json(self.path / MANIFEST, {**self.manifest, **redact_tree(fields)})

    def rewrite(self, records: Iterable[EpisodeRecord]) -> None:
        """Replace every row by ``records`` at once (atomic), for runs whose source of truth is another file
        (the real-robot journal, ``indgen_vla.app.real.store``): the Parquet file is a view rebuilt from it."""
        rows = {}
        for rec in records:
            if rec.key in rows:
                raise RunDirError(
                    f"episode {rec.key} appears twice; refusing to write {self.path / EPISODES}"
                )
            rows[rec.key] = _row(rec)
        (self.path / JOURNAL).unlink(missing_ok=True)  # the source of truth is elsewhere: nothing to replay
        self._rows = rows
        self._flush()

    def _flush(self) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        t0 = time.monotonic()
        rows = self._load()
        ordered = [rows[k] for k in sorted(rows, key=lambda k: (k[1], k[0], k[2], k[3]))]
        table = pa.Table.from_pylist(ordered, schema=_schema())
        sink = pa.BufferOutputStream()
        pq.write_table(table, sink)
        atomic_write_bytes(self.path / EPISODES, sink.getvalue().to_pybytes())
        (self.path / JOURNAL).unlink(
            missing_ok=True
        )  # after the rewrite: a kill between the two replays rows
        self._pending, self._flushed_at = False, time.monotonic()
        self._flush_cost = self._flushed_at - t0

    def episodes(self):
        """All recorded episodes as a pandas DataFrame with the columns of docs/contracts.md."""
        df = self._stored_frame()
        return episodes_frame(list(self._load().values())) if df is None else _typed(df)


def _row(rec: EpisodeRecord) -> dict[str, Any]:
    """An episode's Parquet row, the policy spec's secrets masked in its ``policy`` and ``error``."""
    row = asdict(rec)
    row["policy"], row["error"] = redact(row["policy"]), row["error"] and redact(row["error"])
    return row


def _first_difference(diff: list[str], was: Mapping[str, Any], now: Mapping[str, Any]) -> str:
    """The first differing plan field's two values, when short enough for the one error line ("; episodes: 6 in the
    run, 8 now"), so the user sees which command made the run."""
    if not diff:
        return ""
    k = diff[0]
    a, b = (json.dumps(redact_tree(p.get(k)), default=str) for p in (was, now))  # an api_key stays masked
    return f"; {k}: {a} in the run, {b} now" if len(a) + len(b) <= 120 else ""


def _resume_hint(manifest: Mapping[str, Any]) -> str:
    """How to resume the run of ``manifest``: its own command, or for a merge of shards (``indgen merge``) the one
    evaluate command that plans their union, if any."""
    merged = manifest.get("merged_from")
    if not isinstance(merged, dict):
        return "use a new --out or repeat the original command to resume"
    if merged.get("resume"):
        return f"it is a merge of shards (indgen merge): resume it with {merged['resume']}"
    return (f"it is a merge of shards (indgen merge) that no single evaluate command resumes "
            f"({merged.get('resume_note', 'see its manifest')}): finish the shards and merge them again")  # fmt: skip


def episodes_frame(rows: list[dict]):
    """Episode rows as the DataFrame ``RunDir.episodes`` returns (``[]``: a run with none yet, same dtypes)."""
    import pandas as pd

    return _typed(pd.DataFrame(rows, columns=list(COLUMNS)))


def _typed(df):
    """The dtypes of the episode columns."""
    return df.astype({"level": "int64", "episode": "int64", "seed": "int64", "steps": "int64",
                      "success": "bool", "progress": "Int8"})  # fmt: skip
