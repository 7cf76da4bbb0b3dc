"""The service's persistent state: one SQLite file in WAL mode (readers never wait for the writer), its
schema versioned by ``PRAGMA user_version`` and brought up to date by the migrations below, in order.

A run is a row: what was asked (scenarios, seed, DUT, mode, priority), where it stands (status,
progress, the worker's process), and what came of it (exit code, error, per-scenario verdicts and
measurements). The queue is the rows with status ``queued``, ordered by priority (higher first), then
age; claiming one is a single write transaction (BEGIN IMMEDIATE), so two workers, in one process or
two, never take the same run.
"""

from __future__ import annotations

import builtins
import json
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Final

#: migration k brings the schema from version k to k + 1
MIGRATIONS: Final = (
    """CREATE TABLE runs (
        id INTEGER PRIMARY KEY,
        created REAL NOT NULL,
        status TEXT NOT NULL,
        priority INTEGER NOT NULL,
        mode TEXT NOT NULL,
        seed INTEGER NOT NULL,
        scenarios TEXT NOT NULL,
        dut TEXT NOT NULL,
        started REAL,
        finished REAL,
        exit_code INTEGER,
        error TEXT,
        progress REAL NOT NULL DEFAULT 0,
        results TEXT NOT NULL DEFAULT '[]',
        pid INTEGER
    );
    CREATE INDEX runs_queue ON runs (status, mode, priority, created);""",
    # the bench is leased: its holder renews the lease while it runs there; a holder that died stops
    # renewing and the lease expires, so another worker (in this service or another) can take it
    """CREATE TABLE leases (
        resource TEXT PRIMARY KEY,
        holder TEXT NOT NULL,
        expires REAL NOT NULL
    );""",
    # who asked for the run: "api" (HTTP, the page, rig submit) or "plc" (the test cell's Modbus TCP)
    "ALTER TABLE runs ADD COLUMN origin TEXT NOT NULL DEFAULT 'api'",
    # scenarios are stored by content (store.py): a name points at a version, the latest row of its
    # name here (the rows before it are its history); a run records the version of each scenario it
    # names when it is queued ({name: SHA-256}; '{}': queued before versions, pinned when it starts)
    """CREATE TABLE scenario_versions (
        id INTEGER PRIMARY KEY,
        name TEXT NOT NULL,
        sha256 TEXT NOT NULL,
        created REAL NOT NULL
    );
    CREATE INDEX scenario_versions_name ON scenario_versions (name, id);
    ALTER TABLE runs ADD COLUMN versions TEXT NOT NULL DEFAULT '{}'""",
    # the farm (docs/farm.md): a bench run's selector ({label: value}; '{}': any bench), the bench it
    # went to, and the benches taken out for maintenance (the benches themselves are the scheduler's)
    """ALTER TABLE runs ADD COLUMN bench TEXT NOT NULL DEFAULT '{}';
    ALTER TABLE runs ADD COLUMN bench_name TEXT;
    CREATE TABLE benches_disabled (
        name TEXT PRIMARY KEY,
        since REAL NOT NULL
    )""",
)
SCHEMA_VERSION: Final = len(MIGRATIONS)
TERMINAL: Final = ("passed", "failed", "error", "cancelled", "interrupted")
STATUSES: Final = ("queued", "running", *TERMINAL)
SQLITE_INT: Final = (-(2**63), 2**63 - 1)  # the ids SQLite can hold
SHORT: Final = 8  # hex digits of a scenario's version shown beside its name
JSON_COLUMNS: Final = ("scenarios", "dut", "results", "versions", "bench")


class Db:
    def __init__(self, path: Path) -> None:
        self.path = path
        self._lock = threading.Lock()
        self._conn = sqlite3.connect(path, isolation_level=None, check_same_thread=False, timeout=30)
        self._conn.row_factory = sqlite3.Row
        self._conn.execute("PRAGMA journal_mode=WAL")
        self._migrate()

    def _migrate(self) -> None:
        with self.transaction() as c:
            version = c.execute("PRAGMA user_version").fetchone()[0]
            if version > SCHEMA_VERSION:
                raise RuntimeError(f"{self.path}: schema version {version} is newer than this rig's "
                                   f"({SCHEMA_VERSION}); use a newer rig or another --data folder")
            for k in range(version, SCHEMA_VERSION):
                for statement in MIGRATIONS[k].split(";"):
                    if statement.strip():
                        c.execute(statement)
                c.execute(f"PRAGMA user_version = {k + 1}")

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction, taken at once (BEGIN IMMEDIATE: no other writer meanwhile)."""
        with self._lock:
            self._conn.execute("BEGIN IMMEDIATE")
            try:
                yield self._conn
            except BaseException:
                self._conn.execute("ROLLBACK")
                raise
            self._conn.execute("COMMIT")

    def close(self) -> None:
        with self._lock:
            self._conn.close()

    # ---- runs ---------------------------------------------------------------------------------

    def submit(self, scenarios: list[str], seed: int, dut: dict[str, str], mode: str, priority: int,
               origin: str = "api", versions: dict[str, str] | None = None,
               bench: dict[str, str] | None = None) -> int:
        """Queues a run; ``versions`` is the SHA-256 of each scenario it names, as they are now;
        ``bench`` a bench run's selector (labels it needs; the farm's)."""
        with self.transaction() as c:
            cur = c.execute("INSERT INTO runs (created, status, priority, mode, seed, scenarios, dut, "
                            "origin, versions, bench) VALUES (?, 'queued', ?, ?, ?, ?, ?, ?, ?, ?)",
                            (time.time(), priority, mode, seed, json.dumps(scenarios), json.dumps(dut),
                             origin, json.dumps(versions or {}), json.dumps(bench or {})))
            assert cur.lastrowid is not None
            return cur.lastrowid

    def claim(self, *modes: str) -> dict[str, Any] | None:
        """The next queued run of these modes (a resource's: a lockstep slot takes lockstep runs and
        sweeps), now running (None: nothing queued)."""
        marks = ", ".join("?" * len(modes))
        with self.transaction() as c:
            row = c.execute(f"SELECT id FROM runs WHERE status = 'queued' AND mode IN ({marks}) "
                            "ORDER BY priority DESC, created, id LIMIT 1", modes).fetchone()
            if row is None:
                return None
            c.execute("UPDATE runs SET status = 'running', started = ? WHERE id = ?",
                      (time.time(), row["id"]))
        return self.get(row["id"])

    def queued(self, mode: str) -> builtins.list[dict[str, Any]]:
        """The queued runs of ``mode`` in the order they are claimed (priority, then age)."""
        with self._lock:
            rows = self._conn.execute("SELECT * FROM runs WHERE status = 'queued' AND mode = ? "
                                      "ORDER BY priority DESC, created, id", (mode,)).fetchall()
        return [_decode(r) for r in rows]

    def claim_run(self, run_id: int, **fields: Any) -> dict[str, Any] | None:
        """This queued run, now running (None: it left the queue meanwhile: cancelled)."""
        if not self.update_if(run_id, "queued", status="running", started=time.time(), **fields):
            return None
        return self.get(run_id)

    def disabled_benches(self) -> set[str]:
        with self._lock:
            return {str(r[0]) for r in self._conn.execute("SELECT name FROM benches_disabled").fetchall()}

    def disable_bench(self, name: str, disabled: bool) -> None:
        with self.transaction() as c:
            if disabled:
                c.execute("INSERT OR IGNORE INTO benches_disabled (name, since) VALUES (?, ?)",
                          (name, time.time()))
            else:
                c.execute("DELETE FROM benches_disabled WHERE name = ?", (name,))

    def update(self, run_id: int, **fields: Any) -> None:
        for k in JSON_COLUMNS:
            if k in fields:
                fields[k] = json.dumps(fields[k])
        sets = ", ".join(f"{k} = ?" for k in fields)
        with self.transaction() as c:
            c.execute(f"UPDATE runs SET {sets} WHERE id = ?", (*fields.values(), run_id))

    def finish(self, run_id: int, status: str, **fields: Any) -> None:
        """Ends a running run; one cancelled meanwhile keeps that status, and gets the rest."""
        if not self.update_if(run_id, "running", status=status, finished=time.time(), **fields):
            self.update(run_id, finished=time.time(), **fields)

    def update_if(self, run_id: int, current: str, **fields: Any) -> bool:
        for k in JSON_COLUMNS:
            if k in fields:
                fields[k] = json.dumps(fields[k])
        sets = ", ".join(f"{k} = ?" for k in fields)
        with self.transaction() as c:
            cur = c.execute(f"UPDATE runs SET {sets} WHERE id = ? AND status = ?", (*fields.values(), run_id,
                                                                                     current))
            return cur.rowcount == 1

    def get(self, run_id: int) -> dict[str, Any] | None:
        if not SQLITE_INT[0] <= run_id <= SQLITE_INT[1]:  # (no such run, rather than an OverflowError)
            return None
        with self._lock:
            row = self._conn.execute("SELECT * FROM runs WHERE id = ?", (run_id,)).fetchone()
            if row is None:
                return None
            return self._positioned(_decode(row))

    def _positioned(self, run: dict[str, Any]) -> dict[str, Any]:
        """The run with its ``label`` and its place in its mode's queue (``position``, 1: next; None
        once it has left the queue)."""
        run["label"] = label(run)
        if run["status"] == "queued":
            run["position"] = self._conn.execute(
                "SELECT COUNT(*) FROM runs WHERE status = 'queued' AND mode = ? AND "
                "(priority > ? OR (priority = ? AND (created < ? OR (created = ? AND id < ?))))",
                (run["mode"], run["priority"], run["priority"], run["created"], run["created"],
                 run["id"])).fetchone()[0] + 1
        else:
            run["position"] = None
        return run

    def list(self, status: str | None = None, scenario: str | None = None, since: float | None = None,
             limit: int = 50, offset: int = 0, firmware: str | None = None,
             origin: str | None = None, mode: str | None = None) -> list[dict[str, Any]]:
        where: list[str] = []
        args: list[object] = []
        for column, value in (("mode", mode), ("origin", origin), ("status", status)):
            if value is not None:  # (the column names are these literals, never a request's)
                where.append(f"{column} = ?")
                args.append(value)
        if since is not None:
            where.append("created >= ?")
            args.append(since)
        if scenario is not None:  # a name among the JSON list (or a sweep's versions), matched whole
            where.append("(EXISTS (SELECT 1 FROM json_each(runs.scenarios) WHERE json_each.value = ?) OR "
                         "EXISTS (SELECT 1 FROM json_each(runs.versions) WHERE json_each.key = ?))")
            args += [scenario, scenario]
        if firmware is not None:
            where.append("json_extract(dut, '$.firmware') = ?")
            args.append(firmware)
        sql = "SELECT * FROM runs" + (" WHERE " + " AND ".join(where) if where else "")
        sql += " ORDER BY id DESC LIMIT ? OFFSET ?"
        with self._lock:
            return [self._positioned(_decode(r))
                    for r in self._conn.execute(sql, (*args, limit, offset)).fetchall()]

    # ---- scenario names -> versions ----------------------------------------------------------------

    def point(self, name: str, sha256: str, replace: bool) -> tuple[str | None, bool]:
        """Points ``name`` at the version ``sha256`` unless it points at another one and ``replace`` is
        False: (the version it pointed at before, whether it points at ``sha256`` now), in one write
        transaction, so two uploads under one name cannot both think they took it first."""
        with self.transaction() as c:
            row = c.execute("SELECT sha256 FROM scenario_versions WHERE name = ? ORDER BY id DESC LIMIT 1",
                            (name,)).fetchone()
            current = None if row is None else str(row["sha256"])
            if current == sha256:
                return current, True
            if current is not None and not replace:
                return current, False
            c.execute("INSERT INTO scenario_versions (name, sha256, created) VALUES (?, ?, ?)",
                      (name, sha256, time.time()))
            return current, True

    def version(self, name: str) -> str | None:
        """The version ``name`` points at (None: no scenario was uploaded under it)."""
        with self._lock:
            row = self._conn.execute("SELECT sha256 FROM scenario_versions WHERE name = ? ORDER BY id DESC "
                                     "LIMIT 1", (name,)).fetchone()
        return None if row is None else str(row["sha256"])

    def names(self) -> dict[str, str]:
        """Every uploaded name and the version it points at, by name."""
        with self._lock:
            rows = self._conn.execute("SELECT name, sha256 FROM scenario_versions v WHERE id = "
                                      "(SELECT MAX(id) FROM scenario_versions WHERE name = v.name) "
                                      "ORDER BY name").fetchall()
        return {str(r["name"]): str(r["sha256"]) for r in rows}

    def history(self, name: str) -> builtins.list[dict[str, Any]]:
        """The versions ``name`` has pointed at, oldest first (a version pointed at again appears again)."""
        with self._lock:
            rows = self._conn.execute("SELECT sha256, created FROM scenario_versions WHERE name = ? "
                                      "ORDER BY id", (name,)).fetchall()
        return [dict(r) for r in rows]

    # ---- leases -------------------------------------------------------------------------------

    def acquire(self, resource: str, holder: str, ttl: float) -> bool:
        """Takes (or renews) ``resource`` for ``holder`` until ``ttl`` seconds from now, unless another
        holder's lease is still running."""
        now = time.time()
        with self.transaction() as c:
            row = c.execute("SELECT holder, expires FROM leases WHERE resource = ?", (resource,)).fetchone()
            if row is not None and row["holder"] != holder and row["expires"] > now:
                return False
            c.execute("INSERT INTO leases (resource, holder, expires) VALUES (?, ?, ?) "
                      "ON CONFLICT (resource) DO UPDATE SET holder = excluded.holder, "
                      "expires = excluded.expires",
                      (resource, holder, now + ttl))
            return True

    def release(self, resource: str, holder: str) -> None:
        with self.transaction() as c:
            c.execute("DELETE FROM leases WHERE resource = ? AND holder = ?", (resource, holder))

    def lease(self, resource: str) -> dict[str, Any] | None:
        with self._lock:
            row = self._conn.execute("SELECT * FROM leases WHERE resource = ?", (resource,)).fetchone()
        return dict(row) if row is not None and row["expires"] > time.time() else None

    def interrupt_running(self) -> int:
        """At start: runs left running by a service that died are interrupted (their processes went
        with it). Returns how many."""
        with self.transaction() as c:
            return c.execute("UPDATE runs SET status = 'interrupted', finished = ?, pid = NULL, "
                             "error = 'the service stopped while this run was running' "
                             "WHERE status = 'running'", (time.time(),)).rowcount


def label(run: dict[str, Any]) -> str:
    """What a run flies, in words for a person: its scenarios as NAME@VERSION (the version's first 8
    hex digits), a sweep's as "sweep of NAME@VERSION", never the server's path of its spec."""
    versions = run.get("versions") or {}
    if run["mode"] == "sweep":
        names = list(versions) or [f"the spec {Path(run['scenarios'][0]).stem[:SHORT]}"]  # (older data)
    else:
        names = run["scenarios"]
    text = ", ".join(f"{n}@{versions[n][:SHORT]}" if n in versions else n for n in names)
    return f"sweep of {text}" if run["mode"] == "sweep" else text


def _decode(row: sqlite3.Row) -> dict[str, Any]:
    run = dict(row)
    for k in JSON_COLUMNS:
        run[k] = json.loads(run[k])
    return run
