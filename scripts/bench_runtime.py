#!/usr/bin/env python3
"""Benchmark of the drone execution environment; prints JSON.

Measures, each in fresh processes:

* ``startup``: time and memory to load a drone program of ~634 MDG nodes (the
  paper's stress test: 733 ms, 4.2 MB heap in Go) and build its runtime (every
  node actor, the HAL actor, both bridges), up to "runtime started".
* ``local_trigger``: cost per node of a one-drone chain of zero-duration actions
  (node actor -> uniform API -> adapter -> next node): the span per node, the
  median and p90 gap between action starts, and the drone's log lines per node.
* ``cross_drone``: latency of a trigger between two drone processes over
  loopback TCP (end of an action on one drone to the start of the next action on
  the other), p50 and p99, from an ``eamos run`` with zero-duration actions.
* ``mission_5000``: framework overhead of a 20-drone, >5000-node mission whose
  actions take no time: start trigger to the last drone resolved, plus the whole
  wall time of ``eamos run`` (compile, spawn 20 processes, run, reports).
* ``net_latency``: the cross-drone trigger latency again, p50/p99, between
  ``eamos-node`` processes started from configs (:mod:`tests.support.netlab`), with
  CURVE on and off (plain, loopback), and with CURVE under 10 % random packet
  loss (iptables in a network namespace; needs root, else reported skipped).
* ``reference_hops``: the floors the two trigger paths are compared with, in
  fresh processes of the same run: a pykka ``tell`` hop (a chain of actors
  passing one message along, per hop) and a raw ZeroMQ CURVE hop between two
  processes on loopback (PUB/SUB both ways, half a round trip, p50/p99); and
  the ratios ``local_trigger`` / pykka hop and ``cross_drone`` p50 / CURVE hop
  (issue 15's targets: at most 5 and 3).
* ``net_bytes``: what one trigger costs on the network: its message (topic +
  msgpack payload), its acknowledgement, and the bytes on the wire (IP packets
  counted by iptables in a namespace, CURVE on and off; needs root).

``--rounds N`` runs the trigger-path sections (``local_trigger``, ``cross_drone``,
``reference_hops``, those selected) N times, interleaved (local, cross, floors;
local, cross, floors; ...), so each ratio is taken against floors measured
minutes apart at most: on a shared machine the floors themselves move by 2x
between runs (the CURVE hop measured 31-75 us within one hour).  The sections
then hold the median figures, ``rounds`` each round's figures and ratios, and
``ratios`` the median of the per-round ratios.

Usage: ``python scripts/bench_runtime.py --json`` (``--quick`` for a smaller run,
``--rounds 5`` for the trigger path's ratios).
"""

from __future__ import annotations

import argparse
import itertools
import json
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# The network lab (namespaces, node processes) is test infrastructure in tests/support.
sys.path.insert(0, str(REPO))
ACTIONS = ("TurnOn", "PreFlightCheck", "Calibrate")


def stress_mission(drones: int, blocks: int, per_drone: int) -> str:
    """K parallel blocks in sequence; in each, every drone runs a chain of payload actions."""
    lines = [f"var D{d} Quadcopter" for d in range(1, drones + 1)]
    lines.append("func SEQ_Main() {")
    lines += [f"    PAR_B{b}()" for b in range(blocks)]
    lines.append("}")
    for b in range(blocks):
        lines.append(f"func PAR_B{b}() {{")
        lines += [f"    SEQ_B{b}_D{d}()" for d in range(1, drones + 1)]
        lines.append("}")
        for d in range(1, drones + 1):
            lines.append(f"func SEQ_B{b}_D{d}() {{")
            lines += [f"    D{d}.{ACTIONS[i % len(ACTIONS)]}()" for i in range(per_drone)]
            lines.append("}")
    return "\n".join(lines) + "\n"


def chain_mission(n: int) -> str:
    body = "\n".join(f"    D1.{ACTIONS[i % len(ACTIONS)]}()" for i in range(n))
    return f"func SEQ_Chain() {{\n{body}\n}}\n"


def ping_pong_mission(hops: int) -> str:
    body = "\n".join(f"    D{1 + i % 2}.TurnOn()" for i in range(hops))
    return f"func SEQ_PingPong() {{\n{body}\n}}\n"


_STARTUP_CHILD = r"""
import json, sys, time, resource, zmq
from pathlib import Path
def rss_mb():
    for line in open('/proc/self/status'):
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
import eamos.actors.runtime, eamos.hal.fake, eamos.program.format  # imports are not start-up
from eamos.actors.runtime import DroneRuntime, NetSettings
from eamos.hal.fake import FakeAdapter
from eamos.program.format import load_program
before = rss_mb()
t0 = time.perf_counter()
program = load_program(Path(sys.argv[1]))
t_load = time.perf_counter() - t0
rt = DroneRuntime(program, FakeAdapter(program.drone, auto=True),
                  NetSettings('tcp://127.0.0.1:0', {}), None)  # plain, loopback
rt.start()
elapsed = time.perf_counter() - t0
after = rss_mb()
rt.stop()
print(json.dumps({"nodes": len(program.nodes), "native_nodes": len(program.native_nodes()),
                  "load_s": round(t_load, 4), "startup_s": round(elapsed, 4),
                  "rss_delta_mb": round(after - before, 1), "rss_mb": round(after, 1)}))
"""


def bench_startup(tmp: Path) -> dict:
    from eamos.compiler import compile_mission

    compiled = compile_mission(stress_mission(20, 10, 25), "stress.go")
    sizes = {name: len(p.nodes) for name, p in compiled.programs.items() if name != "GCS"}
    drone = min(sizes, key=lambda n: abs(sizes[n] - 634))
    path = compiled.programs[drone].save(tmp / f"{drone}.program.json")
    runs = [
        json.loads(
            subprocess.run(
                [sys.executable, "-c", _STARTUP_CHILD, str(path)],
                capture_output=True,
                text=True,
                check=True,
                timeout=300,
            ).stdout
        )
        for _ in range(3)
    ]
    best = min(runs, key=lambda r: r["startup_s"])
    best["meg_nodes"] = compiled.meg.number_of_nodes()
    best["startup_s_runs"] = [r["startup_s"] for r in runs]
    return best


def eamos_run(tmp: Path, name: str, source: str, timeout_s: float = 900) -> dict:
    mission = tmp / f"{name}.go"
    mission.write_text(source)
    fleet = tmp / "fake_fleet.toml"
    fleet.write_text('[defaults.hal]\nadapter = "fake"\n')
    summary = tmp / f"{name}.summary.json"
    t0 = time.perf_counter()
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "eamos.cli",
            "run",
            str(mission),
            "--fleet",
            str(fleet),
            "--plain",
            "--no-svg",
            "--run-dir",
            str(tmp / name),
            "--summary",
            str(summary),
            "--ready-timeout",
            "300",
            "--timeout",
            str(timeout_s),
        ],
        capture_output=True,
        text=True,
        timeout=timeout_s + 300,
        cwd=REPO,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"eamos run {name} failed: {proc.stdout[-2000:]} {proc.stderr[-2000:]}")
    data = json.loads(summary.read_text())
    data["_wall_s"] = wall
    return data


def bench_local(tmp: Path, n: int) -> dict:
    """The chain's span per node; also the median and p90 of the start-to-start gaps
    (robust to a busy machine's stalls) and the log lines the drone wrote per node."""
    data = eamos_run(tmp, "chain", chain_mission(n))
    acts = sorted(data["drones"]["D1"]["actions"], key=lambda a: a["start"])
    span = acts[-1]["end"] - acts[0]["start"]
    gaps = sorted((b["start"] - a["start"]) * 1e6 for a, b in itertools.pairwise(acts))
    logs = [p for p in (tmp / "chain").rglob("*.log") if p.parent.name == "D1"]
    lines = sum(len(p.read_text(encoding="utf-8").splitlines()) for p in logs)
    return {
        "nodes": n,
        "seconds": round(span, 4),
        "per_node_us": round(span / (n - 1) * 1e6, 1),
        "gap_p50_us": round(statistics.median(gaps), 1),
        "gap_p90_us": round(gaps[int(0.9 * (len(gaps) - 1))], 1),
        "log_lines_per_node": round(lines / n, 2),
    }


def bench_cross(tmp: Path, hops: int) -> dict:
    data = eamos_run(tmp, "pingpong", ping_pong_mission(hops))
    acts = sorted(
        (a for d in ("D1", "D2") for a in data["drones"][d]["actions"]), key=lambda a: a["start"]
    )
    lat = [(b["start"] - a["end"]) * 1e3 for a, b in itertools.pairwise(acts)]
    lat.sort()
    return {
        "hops": len(lat),
        "p50_ms": round(statistics.median(lat), 3),
        "p99_ms": round(lat[int(0.99 * (len(lat) - 1))], 3),
        "max_ms": round(lat[-1], 3),
    }


def bench_mission(tmp: Path, drones: int, blocks: int, per_drone: int) -> dict:
    from eamos.compiler import compile_mission

    source = stress_mission(drones, blocks, per_drone)
    meg_nodes = compile_mission(source, "m.go").meg.number_of_nodes()
    data = eamos_run(tmp, "stress", source)
    starts = [a["start"] for r in data["drones"].values() for a in r["actions"]]
    ends = [a["end"] for r in data["drones"].values() for a in r["actions"]]
    return {
        "drones": drones,
        "meg_nodes": meg_nodes,
        "actions": len(starts),
        "overhead_s": round(data["duration_s"], 3),
        "first_to_last_action_s": round(max(ends) - min(starts), 3),
        "eamos_run_wall_s": round(data["_wall_s"], 2),
        "triggers_sent": sum(r["triggers_sent"] for r in data["drones"].values()),
    }


# -- reference hops: what a trigger path is compared with --------------------------------

_PYKKA_CHILD = r"""
import json, sys, threading, time, pykka
n, rounds = int(sys.argv[1]), int(sys.argv[2])
done = threading.Event()
class Hop(pykka.ThreadingActor):
    def __init__(self, nxt):
        super().__init__()
        self.nxt = nxt
    def on_receive(self, message):
        if self.nxt is None:
            done.set()
        else:
            self.nxt.tell(message)
chain = None
for _ in range(n):
    chain = Hop.start(chain)
best = float("inf")
for _ in range(rounds):
    done.clear()
    t0 = time.perf_counter()
    chain.tell({"hop": 1})
    done.wait(60)
    best = min(best, (time.perf_counter() - t0) / (n - 1))
pykka.ActorRegistry.stop_all()
print(json.dumps({"actors": n, "per_hop_us": round(best * 1e6, 1)}))
"""

_CURVE_ECHO = r"""
import sys, zmq
server_pub, server_sec, client_pub, client_sec, port_me, port_peer, n = sys.argv[1:8]
ctx = zmq.Context()
pub = ctx.socket(zmq.PUB)
pub.curve_server = True
pub.curve_publickey, pub.curve_secretkey = server_pub.encode(), server_sec.encode()
pub.bind(f"tcp://127.0.0.1:{port_me}")
sub = ctx.socket(zmq.SUB)
sub.curve_serverkey = server_pub.encode()
sub.curve_publickey, sub.curve_secretkey = client_pub.encode(), client_sec.encode()
sub.setsockopt(zmq.SUBSCRIBE, b"")
sub.connect(f"tcp://127.0.0.1:{port_peer}")
ping = sys.argv[8] == "ping"
import time, json
lat = []
if ping:
    while True:  # until the echo is subscribed and answering
        pub.send(b"hello")
        if sub.poll(100):
            sub.recv()
            break
    while sub.poll(200):
        sub.recv()
    for _ in range(int(n)):
        t0 = time.perf_counter()
        pub.send(b"x" * 90)
        sub.recv()
        lat.append((time.perf_counter() - t0) / 2 * 1e3)
    pub.send(b"end")
    lat.sort()
    print(json.dumps({"hops": len(lat), "p50_ms": round(lat[len(lat) // 2], 4),
                      "p99_ms": round(lat[int(0.99 * (len(lat) - 1))], 4)}))
else:
    while True:
        msg = sub.recv()
        if msg == b"end":
            break
        pub.send(msg)
"""


def bench_reference_hops(hops: int) -> dict:
    """A pykka tell hop and a raw ZeroMQ CURVE hop between processes (see the docstring)."""
    import zmq

    pykka = subprocess.run(
        [sys.executable, "-c", _PYKKA_CHILD, "200", "20"],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    server_pub, server_sec = (k.decode() for k in zmq.curve_keypair())
    client_pub, client_sec = (k.decode() for k in zmq.curve_keypair())
    from eamos.ground import free_ports

    a, b = free_ports(2)
    keys = [server_pub, server_sec, client_pub, client_sec]
    echo = subprocess.Popen(
        [sys.executable, "-c", _CURVE_ECHO, *keys, str(b), str(a), str(hops), "echo"],
        stdout=subprocess.DEVNULL,
    )
    try:
        ping = subprocess.run(
            [sys.executable, "-c", _CURVE_ECHO, *keys, str(a), str(b), str(hops), "ping"],
            capture_output=True,
            text=True,
            check=True,
            timeout=300,
        )
    finally:
        echo.wait(30)
    return {
        "pykka_tell": json.loads(pykka.stdout.strip().splitlines()[-1]),
        "zmq_curve": json.loads(ping.stdout.strip().splitlines()[-1]),
    }


# -- network: CURVE on/off, loss, bytes -------------------------------------------------


def _fleet_run(
    tmp: Path, name: str, source: str, secure: bool, loss: float = 0.0, net: dict | None = None
) -> dict:
    """Run ``source`` with eamos-node processes from configs; return the GCS summary.

    With ``loss``, every process runs in one fresh network namespace whose
    loopback drops incoming packets at random (iptables), which needs root.
    """
    from eamos.compiler import compile_mission
    from eamos.ground import free_ports
    from tests.support.netlab import Netns, node_argv, write_fleet

    compiled = compile_mission(source, f"{name}.go")
    names = list(compiled.programs)
    ports = free_ports(len(names))
    bind = {n: f"tcp://127.0.0.1:{p}" for n, p in zip(names, ports, strict=True)}
    hal = {n: {"adapter": "fake"} for n in names if n != "GCS"}
    files = write_fleet(
        compiled.programs,
        tmp / name,
        bind,
        hal=hal,
        secure=secure,
        net=net,
        ready_timeout_s=300.0,
        mission_timeout_s=900.0,
    )
    lab = Netns(["host"], tag=f"bench{name}") if loss else None
    procs = []
    try:
        if lab is not None:
            lab.up()
            lab.run(
                "host",
                "iptables",
                "-A",
                "INPUT",
                "-i",
                "lo",
                "-m",
                "statistic",
                "--mode",
                "random",
                "--probability",
                f"{loss:.3f}",
                "-j",
                "DROP",
            )
        for n in names:
            argv = node_argv(files.configs[n])
            argv = lab.argv("host", argv) if lab is not None else argv
            out = (tmp / name / f"{n}.out").open("wb")
            procs.append(subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, cwd=REPO))
            out.close()
        procs[names.index("GCS")].wait(1200)
        for proc in procs:
            proc.wait(120)
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
        if lab is not None:
            lab.down()
    summary = files.summary()
    if summary is None or not summary["ok"]:
        raise RuntimeError(f"{name}: fleet run failed: {summary and summary['outcome']}")
    return summary


def _latencies(summary: dict) -> dict:
    acts = sorted(
        (a for d in ("D1", "D2") for a in summary["drones"][d]["actions"]), key=lambda a: a["start"]
    )
    lat = sorted((b["start"] - a["end"]) * 1e3 for a, b in itertools.pairwise(acts))
    nets = [summary["drones"][d]["net"] for d in ("D1", "D2")]
    return {
        "hops": len(lat),
        "p50_ms": round(statistics.median(lat), 3),
        "p99_ms": round(lat[int(0.99 * (len(lat) - 1))], 3),
        "max_ms": round(lat[-1], 3),
        "retransmissions": sum(n["retransmissions"] for n in nets),
        "duplicates_dropped": sum(n["duplicates_dropped"] for n in nets),
    }


def bench_net_latency(tmp: Path, hops: int, loss_hops: int) -> dict:
    from tests.support.netlab import lab_unavailable

    out = {
        "curve": _latencies(_fleet_run(tmp, "curve", ping_pong_mission(hops), True)),
        "plain": _latencies(_fleet_run(tmp, "plain", ping_pong_mission(hops), False)),
    }
    why = lab_unavailable()
    if why is None:
        summary = _fleet_run(tmp, "loss10", ping_pong_mission(loss_hops), True, loss=0.10)
        out["curve_loss_10pct"] = _latencies(summary)
    else:
        out["curve_loss_10pct"] = {"skipped": why}
    return out


_BYTES_CHILD = r"""
import json, subprocess, sys, threading, zmq
from pathlib import Path
from eamos.net import wire
from eamos.net.keys import FleetKeys, create_fleet_keys
from eamos.net.link import Link, LinkSettings
secure, n, tmp = sys.argv[1] == "curve", int(sys.argv[2]), Path(sys.argv[3])
keys = create_fleet_keys(tmp / "keys", ["A", "B"], force=True) if secure else None
ep = {"A": "tcp://127.0.0.1:7101", "B": "tcp://127.0.0.1:7102"}
got, cond = [], threading.Condition()
def on_b(m):
    with cond:
        got.append(m); cond.notify_all()
links = {}
for me, other, cb in (("B", "A", on_b), ("A", "B", lambda m: None)):
    ctx = zmq.Context()
    link = Link(ctx, me, "bench", ep[me], keys=FleetKeys.load(keys / me, me) if keys else None,
                settings=LinkSettings())  # the defaults: acks ride on 1 s heartbeats
    link.connect({other: ep[other]}, (), cb)
    links[me] = link
assert links["A"].wait_subscribed([wire.topic_to("B")], 30)
def counters():
    out = subprocess.run(["iptables", "-L", "OUTPUT", "-v", "-x", "-n"], capture_output=True,
                         text=True, check=True).stdout.splitlines()
    pkts, byts = out[2].split()[:2]
    return int(pkts), int(byts)
assert links["B"].wait_subscribed([wire.topic_to("A")], 30)  # the acks' way back is open too
p0, b0 = counters()
for i in range(n):
    links["A"].send(wire.Trigger("bench", "A", "B", "n1", "n2", (i,), "done"))
    with cond:
        assert cond.wait_for(lambda: len([m for m in got if isinstance(m, wire.Trigger)]) > i, 30)
assert links["A"].flush(30)
p1, b1 = counters()
stats = links["A"].stats()
acks = links["B"].stats()
print(json.dumps({"packets": p1 - p0, "bytes": b1 - b0,
                  "trigger_bytes": stats["bytes_sent_by_type"]["Trigger"] / n,
                  "ack_bytes": (acks["bytes_sent_by_type"].get("Ack", 0)
                                + acks["bytes_sent_by_type"].get("Heartbeat", 0)) / n}))
for link in links.values():
    link.close()
"""


def bench_net_bytes(tmp: Path, n: int) -> dict:
    """Bytes per trigger, one trigger in flight at a time (as in a mission's chains)."""
    from eamos.net.incarnation import new_incarnation
    from eamos.net.wire import WIRE_VERSION, Ack, Heartbeat, Trigger, encode
    from tests.support.netlab import Netns, lab_unavailable

    mission = "0123456789abcdef"  # ids are 16 hex digits
    # Real incarnations (per-process numbers, about 8 bytes each on the wire).
    mine, theirs = new_incarnation(), new_incarnation()
    sample = Trigger(
        mission, "Drone1", "Drone2", "n12", "n34", (0,), "done", seq=12, incarnation=mine
    )
    ack = Ack(mission, "Drone2", "Drone1", 12, 0, dest_incarnation=mine, incarnation=theirs)
    beat = Heartbeat(
        mission,
        "Drone2",
        {"Drone1": 40, "GCS": 3},
        0,
        acks={"Drone1": 12},
        known={"Drone1": mine},
        incarnation=theirs,
    )
    out: dict = {
        "trigger_message_bytes": sum(map(len, encode(sample))),
        "explicit_ack_message_bytes": sum(map(len, encode(ack))),
        "heartbeat_message_bytes": sum(map(len, encode(beat))),
        "note": f"message = topic + msgpack payload (wire v{WIRE_VERSION}).  Steady traffic "
        "is acked by the 1 s heartbeats, explicit acks only for gaps, duplicates and reports.  "
        "on_wire = IP packets both ways on loopback per trigger, one trigger in flight at a "
        "time, incl. ZMTP/CURVE framing, TCP/IP headers, TCP acks and the heartbeats meanwhile",
    }
    why = lab_unavailable()
    if why is not None:
        out["on_wire"] = {"skipped": why}
        return out
    out["on_wire"] = {}
    for mode in ("plain", "curve"):
        lab = Netns(["host"], tag=f"bytes{mode}")
        try:
            lab.up()
            lab.run("host", "iptables", "-A", "OUTPUT", "-o", "lo")  # a counting rule
            proc = subprocess.run(
                lab.argv("host", [sys.executable, "-c", _BYTES_CHILD, mode, str(n), str(tmp)]),
                capture_output=True,
                text=True,
                timeout=600,
                cwd=REPO,
            )
        finally:
            lab.down()
        if proc.returncode != 0:
            raise RuntimeError(f"net_bytes {mode}: {proc.stderr[-2000:]}")
        data = json.loads(proc.stdout)
        out["on_wire"][mode] = {
            "bytes_per_trigger": round(data["bytes"] / n, 1),
            "packets_per_trigger": round(data["packets"] / n, 2),
            "trigger_message_bytes": round(data["trigger_bytes"], 1),
            "ack_and_heartbeat_bytes_per_trigger": round(data["ack_bytes"], 1),
        }
    return out


#: The sections ``--rounds`` repeats (the trigger path and its floors).
TRIGGER_PATH = ("local_trigger", "cross_drone", "reference_hops")
#: Per round: the ratio's name, and where its numerator and denominator are.
RATIOS = {
    "local_trigger_x_pykka_tell": (("local_trigger", "per_node_us"), ("pykka_tell", "per_hop_us")),
    "cross_drone_p50_x_zmq_curve_p50": (("cross_drone", "p50_ms"), ("zmq_curve", "p50_ms")),
}


def add_ratios(figures: dict) -> None:
    """The trigger paths against their floors of the same round, in place."""
    refs = figures.get("reference_hops")
    if refs and "local_trigger" in figures:
        hop = refs["pykka_tell"]["per_hop_us"]
        local = figures["local_trigger"]
        local["x_pykka_tell"] = round(local["per_node_us"] / hop, 1)
        local["gap_p50_x_pykka_tell"] = round(local["gap_p50_us"] / hop, 1)
    if refs and "cross_drone" in figures:
        figures["cross_drone"]["x_zmq_curve_p50"] = round(
            figures["cross_drone"]["p50_ms"] / refs["zmq_curve"]["p50_ms"], 1
        )


def merge_rounds(rounds: list[dict]) -> dict:
    """Each trigger-path figure's median over ``rounds``, each round's figures, and the
    median of the per-round ratios (each against its own round's floors)."""
    merged: dict = {}
    for section in TRIGGER_PATH:
        per_round = [r[section] for r in rounds if section in r]
        if per_round:
            merged[section] = _median_tree(per_round)
    per_round_ratios = []
    for r in rounds:
        refs = r.get("reference_hops", {})
        ratios = {}
        for name, ((sec, key), (ref, ref_key)) in RATIOS.items():
            if sec in r and ref in refs:
                ratios[name] = round(r[sec][key] / refs[ref][ref_key], 2)
        per_round_ratios.append(ratios)
    merged["rounds"] = [dict(r, ratios=x) for r, x in zip(rounds, per_round_ratios, strict=True)]
    names = {n for x in per_round_ratios for n in x}
    merged["ratios"] = {
        n: {
            "median": round(statistics.median(x[n] for x in per_round_ratios if n in x), 2),
            "each": [x.get(n) for x in per_round_ratios],
        }
        for n in sorted(names)
    }
    return merged


def _median_tree(items: list) -> object:
    """The median of numbers at the same place in ``items`` (dicts nested alike)."""
    first = items[0]
    if isinstance(first, dict):
        return {k: _median_tree([i[k] for i in items if k in i]) for k in first}
    if isinstance(first, int | float) and not isinstance(first, bool):
        return round(statistics.median(items), 4)
    return first


def sections(tmp: Path, quick: bool) -> list[tuple[str, Callable[[], dict]]]:
    """Every section's name and how to run it, writing into ``tmp``."""
    return [
        ("startup", lambda: bench_startup(tmp)),
        ("local_trigger", lambda: bench_local(tmp, 200 if quick else 2000)),
        ("cross_drone", lambda: bench_cross(tmp, 100 if quick else 1000)),
        ("reference_hops", lambda: bench_reference_hops(200 if quick else 2000)),
        ("mission_5000", lambda: bench_mission(tmp, 4 if quick else 20, 5 if quick else 10, 25)),
        (
            "net_latency",
            lambda: bench_net_latency(tmp, 100 if quick else 1000, 50 if quick else 300),
        ),
        ("net_bytes", lambda: bench_net_bytes(tmp, 50 if quick else 500)),
    ]


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--json", action="store_true", help="print only the JSON result")
    parser.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    parser.add_argument(
        "--only", nargs="+", metavar="SECTION", help="run only these sections (default: all)"
    )
    parser.add_argument(
        "--rounds",
        type=int,
        default=1,
        metavar="N",
        help="interleaved rounds of the trigger-path sections (see above; default 1)",
    )
    args = parser.parse_args()
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp_name:
        rounds: list[dict] = []
        for r in range(max(1, args.rounds)):
            # A folder per round: a run folder reused would append to the last round's logs.
            tmp = Path(tmp_name) / f"round-{r + 1}"
            tmp.mkdir()
            figures: dict = {}
            for name, step in sections(tmp, args.quick):
                if (args.only and name not in args.only) or (r > 0 and name not in TRIGGER_PATH):
                    continue
                if not args.json:
                    print(f"... {name} (round {r + 1})", file=sys.stderr, flush=True)
                figures[name] = step()
            add_ratios(figures)
            rounds.append(figures)
        out.update(rounds[0])
        if len(rounds) > 1:
            out.update(merge_rounds(rounds))
    out["targets"] = {"startup_s": 0.2, "cross_drone_p99_ms": 2.0, "mission_5000_overhead_s": 5.0}
    print(json.dumps(out, indent=None if args.json else 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
