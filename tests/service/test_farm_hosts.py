"""The farm across hosts on one machine: two network namespaces made by the test (`ip netns`, veth pairs
on a private bridge in a third, addresses on a private /24), each a host with a lockstep `dask worker`
and a `rig bench-host` (its own virtual bridge, its own TMPDIR); the scheduler and `rig serve --engine`
on this host's end of the link. Every Dask connection is TLS (Dask's Security, with a self-signed
certificate the test makes with openssl): a worker listening beyond loopback needs it. Bench runs land
on the bench their selector names; lockstep runs spread over the workers of both namespaces; killing
one bench host mid-run interrupts its run only. Needs root and iproute2 (tools/test-packages.sh);
skips with the reason otherwise. Nothing multicasts; everything binds the test's addresses."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.service.test_api import Service, start, stop, until_line
from tests.service.test_benches import drain, judged_bench_run
from tests.sweep.test_sweep_cli import DASK, scheduler_file_written
from tests.waits import wait_file

IP = shutil.which("ip") or "/usr/sbin/ip"


def sh(*args: str) -> None:
    subprocess.run([IP, *args], check=True, capture_output=True, timeout=30)


@dataclass
class Net:
    prefix: str  # "10.254.N."
    tag: str
    namespaces: list[str] = field(default_factory=list)

    def ns(self, k: int) -> str:
        return f"rig{self.tag}-{k}"


def why_no_namespaces() -> str | None:
    if os.geteuid() != 0:
        return "making network namespaces needs root"
    if not os.path.exists(IP):
        return "iproute2's ip is not installed (tools/test-packages.sh installs it)"
    if shutil.which("openssl") is None:
        return "openssl is not installed (tools/test-packages.sh installs it)"
    return None


@pytest.fixture
def net() -> Iterator[Net]:
    """Namespaces 1 and 2 (the bench hosts) and a hub with a bridge; this host joins it as PREFIX.1."""
    reason = why_no_namespaces()
    if reason:
        pytest.skip(reason)
    used = subprocess.run([IP, "-4", "addr"], capture_output=True, text=True).stdout
    third = next(n for n in range(10, 250) if f"10.254.{n}." not in used)
    n = Net(f"10.254.{third}.", secrets.token_hex(2))
    try:
        try:  # (the first command inside one too: in a chroot whose / is no mount point, `ip -n` cannot
            # remount /sys in the namespace: "mount --make-rslave / failed")
            sh("netns", "add", n.ns(0))
            n.namespaces.append(n.ns(0))
            sh("-n", n.ns(0), "link", "add", "br0", "type", "bridge")
        except subprocess.CalledProcessError as e:
            pytest.skip(f"network namespaces cannot be made here: {e.stderr.decode().strip()}")
        sh("-n", n.ns(0), "link", "set", "br0", "up")
        for k in (1, 2, 3):  # 1: this host (no namespace of its own), 2 and 3: the bench hosts
            inside = f"v{n.tag}h{k}"
            peer = f"v{n.tag}p{k}"
            where = [] if k == 1 else ["netns", n.ns(k)]
            if k > 1:
                sh("netns", "add", n.ns(k))
                n.namespaces.append(n.ns(k))
                sh("-n", n.ns(k), "link", "set", "lo", "up")
            sh("link", "add", inside, "netns", n.ns(0), "type", "veth", "peer", "name", peer, *where)
            sh("-n", n.ns(0), "link", "set", inside, "master", "br0", "up")
            on = [] if k == 1 else ["-n", n.ns(k)]
            sh(*on, "addr", "add", f"{n.prefix}{k}/24", "dev", peer)
            sh(*on, "link", "set", peer, "up")
        yield n
    finally:
        for name in reversed(n.namespaces):  # (the veths go with them, this host's end too)
            subprocess.run([IP, "netns", "del", name], capture_output=True, timeout=30)


def certificate(folder: Path) -> list[str]:
    """A self-signed certificate (its own CA) and its key: the TLS options of every party."""
    cert, key = folder / "cert.pem", folder / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj",
                    "/CN=rig-farm-test", "-keyout", str(key), "-out", str(cert)], check=True,
                   capture_output=True, timeout=60)
    return ["--tls-ca-file", str(cert), "--tls-cert", str(cert), "--tls-key", str(key)]


@dataclass
class Hosts:
    address: str
    svc: Service
    tmp: dict[int, Path]  # each bench host's TMPDIR
    bench_hosts: dict[str, subprocess.Popen[str]]


@pytest.fixture
def hosts(net: Net, tmp_path: Path) -> Iterator[Hosts]:
    tls = certificate(tmp_path)
    procs: list[subprocess.Popen[str]] = []
    tmp = {k: Path(tempfile.mkdtemp(prefix=f"rig-ns{k}-", dir="/tmp")) for k in (1, 2, 3)}
    svc = None
    try:
        info = tmp_path / "scheduler.json"
        procs.append(subprocess.Popen(
            [str(DASK), "scheduler", "--host", f"{net.prefix}1", "--port", "0", "--protocol", "tls",
             "--no-dashboard", "--scheduler-file", str(info), *tls],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True,
            env={**os.environ, "TMPDIR": str(tmp[1])}))
        assert wait_file([info], ready=scheduler_file_written) == info, "the scheduler did not start"
        address = json.loads(info.read_text())["address"]
        assert address.startswith(f"tls://{net.prefix}1:")
        bench_hosts = {}
        for k, name in ((2, "a"), (3, "b")):
            env = {**os.environ, "TMPDIR": str(tmp[k])}
            inside = [IP, "netns", "exec", net.ns(k)]
            procs.append(subprocess.Popen(
                [*inside, str(DASK), "worker", address, "--host", f"{net.prefix}{k}", "--nthreads", "1",
                 "--no-nanny", "--no-dashboard", "--name", f"lockstep-{k}", *tls],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True, env=env, cwd=tmp[k]))
            host = subprocess.Popen(
                [*inside, sys.executable, "-m", "rig.cli", "bench-host", "--engine", address, "--bridge",
                 "virtual", "--name", name, "--label", f"site={name}", "--host", f"{net.prefix}{k}", *tls],
                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp[k])
            procs.append(host)
            until_line(host, "joined")
            drain(host)
            bench_hosts[name] = host
        from distributed import Client
        from distributed.security import Security

        security = Security(tls_ca_file=tls[1], tls_client_cert=tls[3], tls_client_key=tls[5],
                            require_encryption=True)
        with Client(address, timeout=60, security=security) as c:
            c.wait_for_workers(4, timeout=60)
        svc = start(tmp_path / "data", "--engine", address, *tls)
        yield Hosts(address, svc, tmp, bench_hosts)
    finally:
        if svc is not None:
            stop(svc)
        for p in reversed(procs):
            p.send_signal(signal.SIGKILL)
            p.wait(timeout=30)
        for folder in tmp.values():
            shutil.rmtree(folder, ignore_errors=True)


def flown_in(svc: Service, run_id: int, scenario: str) -> Path:
    """The TMPDIR the run flew in (its result.json names the scenario file the worker wrote there)."""
    result = json.loads((svc.data / "runs" / str(run_id) / scenario / "result.json").read_text())
    return Path(result["metadata"]["scenario_file"]).parents[3]


# paced: its bench runs fly in real time, so it runs in make test's second part, alone; a bench run
# starved by the host (twice) makes the test inconclusive, never a failure of the run
@pytest.mark.paced
def test_benches_and_lockstep_runs_across_namespaces(hosts: Hosts) -> None:
    svc = hosts.svc
    # lockstep runs spread over the workers of both namespaces
    ids = [svc.call("POST", "/api/runs", {"scenarios": ["gust_rejection"], "seed": s})[1]["id"]
           for s in (1, 2)]
    for run_id in ids:
        assert svc.follow(run_id)["status"] == "passed"
    assert {flown_in(svc, i, "gust_rejection") for i in ids} == {hosts.tmp[2], hosts.tmp[3]}
    # bench runs land on their bench, in its namespace; killing a's host mid-run interrupts a's run only
    _, on_a = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "mode": "bridge",
                                             "bench": {"site": "a"}})
    _, on_b = svc.call("POST", "/api/runs", {"scenarios": ["gust_rejection"], "mode": "bridge",
                                             "bench": {"site": "b"}})
    svc.flying(on_a["id"])
    hosts.bench_hosts["a"].send_signal(signal.SIGKILL)  # (its run has 10 s of flight in real time)
    gone = svc.follow(on_a["id"])
    assert gone["status"] == "interrupted" and gone["bench_name"] == "a" and "not run again" in gone["error"]
    done = judged_bench_run(svc, "gust_rejection", {"site": "b"}, on_b["id"])
    assert done["status"] == "passed" and done["bench_name"] == "b", done
    assert flown_in(svc, int(str(done["id"])), "gust_rejection") == hosts.tmp[3]
    benches = {b["name"]: b["state"] for b in svc.call("GET", "/api/benches")[1]}
    assert benches == {"a": "offline", "b": "free"}
    assert judged_bench_run(svc, "gust_rejection", {"site": "b"})["status"] == "passed"  # b goes on
