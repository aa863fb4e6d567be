"""Analyse a run folder (paper VII-B/C, Table 7): timelines, trajectories, triggers, durations.

A run folder is what ``eamos run`` writes, or a roll-out's folder after
``eamos start`` and ``eamos logs fetch``: ``summary.json``, ``logs/<Drone>/``
(``mission.log``, ``uniform.log``, ``adapter.log``; see ``docs/logs.md``),
``programs/`` and, for a roll-out, ``rollout.json``.

The functions here are what ``notebooks/analyse_run.ipynb`` calls and what
``eamos report RUN_DIR`` puts on one self-contained HTML page::

    run = load_run("runs/experiment_b-20260101-120000")
    table7(run)            # MDG nodes/arcs against triggers received/sent, per drone
    durations(run)         # mission, roll-out steps, per drone and per action
    plot_gantt(run)        # each drone's actions over time
    plot_xy(run); plot_z(run)
    write_html(run.run_dir)

Times are seconds since the start trigger (``summary.json`` ``started``); the
logs and the summary share one wall clock (see ``docs/logs.md``).
"""

from __future__ import annotations

import base64
import contextlib
import html
import io
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .ground.summary import ActionEntry, DroneReport, RunSummary
from .hal.api import POSITION_LOG_HZ
from .logs import LOG_NAMES, read_log
from .program.format import ProgramError, load_program

RESULT_COLOURS = {"ok": "#4c9f70", "failed": "#d1495b", "caught": "#8d6a9f", "cancelled": "#edae49"}
_DASHES = ("-", "--", ":", "-.")
DRONE_COLOURS = ("#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")


class ReportError(Exception):
    """The folder is not a run folder (no readable ``summary.json``)."""


@dataclass
class Table:
    """Rows of plain values; shows as HTML in a notebook and as text elsewhere."""

    columns: list[str]
    rows: list[list[Any]]
    title: str = ""

    def records(self) -> list[dict[str, Any]]:
        """One dict per row (what ``pandas.DataFrame(table.records())`` takes)."""
        return [dict(zip(self.columns, row, strict=True)) for row in self.rows]

    @property
    def _headed(self) -> bool:
        """False for a key/value table (every column title empty): no header row."""
        return any(self.columns)

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        thead = f"<thead><tr>{head}</tr></thead>" if self._headed else ""
        body = "".join(
            "<tr>" + "".join(f"<td>{html.escape(_fmt(v))}</td>" for v in row) + "</tr>"
            for row in self.rows
        )
        caption = f"<caption>{html.escape(self.title)}</caption>" if self.title else ""
        return f'<table class="eamos">{caption}{thead}<tbody>{body}</tbody></table>'

    def __str__(self) -> str:
        cells = [self.columns] if self._headed else []
        cells += [[_fmt(v) for v in row] for row in self.rows]
        if not cells:
            return self.title
        widths = [max(len(str(r[i])) for r in cells) for i in range(len(self.columns))]
        lines = [self.title] if self.title else []
        for row in cells:
            lines.append("  ".join(str(c).ljust(w) for c, w in zip(row, widths, strict=True)))
        return "\n".join(line.rstrip() for line in lines)


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.2f}"
    return "" if value is None else str(value)


@dataclass
class RunData:
    """One run folder, read once."""

    run_dir: Path
    summary: RunSummary
    logs: dict[str, dict[str, list[dict[str, Any]]]] = field(default_factory=dict)
    rollout: dict[str, Any] | None = None

    @property
    def drones(self) -> list[str]:
        """The drones, in the summary's order (the ground station is not one)."""
        return list(self.summary.drones)

    @property
    def t0(self) -> float:
        """The start trigger's wall-clock time: time zero of every plot."""
        return self.summary.started

    def report(self, drone: str) -> DroneReport | None:
        """``drone``'s own report (None when the ground station never received it)."""
        return self.summary.drones[drone].report


def load_run(run_dir: Path | str) -> RunData:
    """Read ``summary.json``, every participant's logs and ``rollout.json`` (if any)."""
    folder = Path(run_dir)
    try:
        summary = RunSummary.read(folder / "summary.json")
    except FileNotFoundError as exc:
        raise ReportError(
            f"{folder}: no summary.json (not a run folder of `eamos run` or `eamos start`)"
        ) from exc
    except (OSError, ValueError, TypeError, AttributeError) as exc:
        raise ReportError(f"{folder / 'summary.json'}: cannot read it: {exc}") from exc
    logs: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for name in [*summary.drones, "GCS"]:
        logs[name] = {kind: read_log(folder / "logs" / name / f"{kind}.log") for kind in LOG_NAMES}
    rollout = None
    if (folder / "rollout.json").exists():
        try:
            rollout = json.loads((folder / "rollout.json").read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError):
            rollout = None
    return RunData(folder, summary, logs, rollout)


def _label(action: ActionEntry) -> str:
    args = ", ".join(f"{a:g}" for a in action.args)
    return f"{action.action}({args})"


def action_bars(run: RunData) -> list[dict[str, Any]]:
    """Every action of every drone: ``drone, label, start_s, end_s, duration_s, result``."""
    bars = []
    for drone in run.drones:
        report = run.report(drone)
        for action in report.actions if report is not None else ():
            bars.append(
                {
                    "drone": drone,
                    "node": action.node,
                    "label": _label(action),
                    "action": action.action,
                    "start_s": action.start - run.t0,
                    "end_s": action.end - run.t0,
                    "duration_s": action.end - action.start,
                    "result": action.result,
                }
            )
    return sorted(bars, key=lambda b: (b["start_s"], b["drone"]))


def trajectories(run: RunData) -> dict[str, dict[str, list[float]]]:
    """Per drone, ``t`` (s since start), ``x``, ``y``, ``z`` (m) from ``adapter.position``.

    The adapters log at ``POSITION_LOG_HZ`` while the vehicle moves and
    nothing while it stands still, so a gap longer than two periods is a
    hold: a point at the held position just before the next line keeps the
    plots from drawing a slow drift through it.  Positions are in the
    drone's own frame (metres from its home); :func:`home_of` moves them to
    the fleet frame.
    """
    out: dict[str, dict[str, list[float]]] = {}
    for drone in run.drones:
        # A simulated drone's vehicle time runs ``speedup`` times faster than the log's.
        period_s = 1.0 / POSITION_LOG_HZ / _speedup(run, drone)
        track: dict[str, list[float]] = {"t": [], "x": [], "y": [], "z": []}
        for event in run.logs.get(drone, {}).get("adapter", []):
            if event.get("event") != "adapter.position":
                continue
            t = float(event["ts"]) - run.t0
            if track["t"] and t - track["t"][-1] > 2.0 * period_s:
                track["t"].append(t - period_s)
                for axis in ("x", "y", "z"):
                    track[axis].append(track[axis][-1])
            track["t"].append(t)
            track["x"].append(float(event["x_m"]))
            track["y"].append(float(event["y_m"]))
            track["z"].append(float(event["z_m"]))
        out[drone] = track
    return out


def _start_event(run: RunData, drone: str) -> dict[str, Any]:
    """``drone``'s ``adapter.start`` line (empty when its log is not here)."""
    for event in run.logs.get(drone, {}).get("adapter", []):
        if event.get("event") == "adapter.start":
            return event
    return {}


def _speedup(run: RunData, drone: str) -> float:
    speedup = _start_event(run, drone).get("speedup", 1.0)
    return float(speedup) if isinstance(speedup, int | float) and speedup > 0 else 1.0


def home_of(run: RunData, drone: str) -> tuple[float, float]:
    """Where ``drone``'s home is in the fleet frame (``home_m`` of its ``adapter.start``).

    (0, 0) when its adapter did not say (real vehicles: their own frame).
    """
    home = _start_event(run, drone).get("home_m")
    if isinstance(home, list) and len(home) == 2:
        return float(home[0]), float(home[1])
    return (0.0, 0.0)


def _counted(run: RunData, drone: str, event: str) -> int | None:
    """Triggers counted in ``mission.log`` (None when the log is not here)."""
    log = run.logs.get(drone, {}).get("mission", [])
    if not log:
        return None
    return sum(1 for e in log if e.get("event") == event)


def table7(run: RunData) -> Table:
    """Paper Table 7 per drone: MDG nodes, internal and external arcs, triggers on the wire.

    ``sent``/``received`` come from the drones' reports (their Out-/In-Bridges);
    ``log sent / received`` recounts them from ``mission.log`` when the logs
    are here.  Every pair reads sent first, as the CLI prints it.  For a
    loop-free mission that ran to its end, the triggers equal the MDG's
    external out/in arcs; ``match`` says whether they do and ``why`` explains
    a "no" (see :func:`mismatch_reason`).
    """
    rows = []
    for drone in run.drones:
        report = run.report(drone)
        mdg = report.mdg if report is not None else {}
        ext_in, ext_out = mdg.get("external_in"), mdg.get("external_out")
        snd, rcv = (
            (report.triggers_sent, report.triggers_received) if report is not None else (None, None)
        )
        log_rcv = _counted(run, drone, "mission.inbridge.received")
        log_snd = _counted(run, drone, "mission.outbridge.sent")
        program = run.run_dir / "programs" / f"{drone}.program.json"
        size_kb = round(program.stat().st_size / 1024, 1) if program.exists() else None
        match = rcv == ext_in and snd == ext_out
        rows.append(
            [
                drone,
                mdg.get("nodes"),
                mdg.get("internal_arcs"),
                f"{ext_out} / {ext_in}",
                f"{snd} / {rcv}",
                "" if log_rcv is None else f"{log_snd} / {log_rcv}",
                match,
                "" if match else mismatch_reason(run, drone),
                size_kb,
            ]
        )
    return Table(
        [
            "drone",
            "MDG nodes",
            "internal arcs",
            "external arcs out / in",
            "triggers sent / received",
            "log sent / received",
            "match",
            "why not",
            "program kB",
        ],
        rows,
        "Triggers against MDG arcs (paper Table 7)",
    )


def mismatch_reason(run: RunData, drone: str) -> str:
    """Why ``drone``'s triggers differ from its MDG's external arcs, in words."""
    report = run.report(drone)
    if report is None:
        return "no report from this drone: its counts are unknown"
    if not run.summary.ok:
        return f"the run did not finish ({run.summary.outcome}): arcs after the stop never fired"
    kinds: set[str] = set()
    in_loop = any(a.iteration for a in report.actions)
    with contextlib.suppress(ProgramError):  # no program here: no explanation from it
        program = load_program(run.run_dir / "programs" / f"{drone}.program.json")
        kinds = {n.kind for n in program.native_nodes()}
        in_loop = in_loop or any(n.loops for n in program.native_nodes())
    if in_loop:
        return "loops: an arc inside a loop fires once per iteration"
    if "if" in kinds:
        return "an If: only the branch taken sends its triggers"
    if any(a.result != "ok" for a in report.actions):
        return "an action failed or was cancelled: what depended on it never ran"
    return "unexplained: compare mission.log with the MDG picture"


def durations(run: RunData) -> Table:
    """Roll-out steps (when rolled out), the mission, and each drone's actions."""
    rows: list[list[Any]] = []
    roll = run.summary.rollout or {}
    table = roll.get("table") or {}
    for name in ("mission compilation", "mission deployment", "total roll-out"):
        if name in table:
            rows.append([name, "", float(table[name]), ""])
    steps = roll.get("durations") or {}
    for step in ("compile", "probe", "deploy", "launch", "ready"):
        if step in steps:
            rows.append([f"  step: {step}", "", float(steps[step]), ""])
    rows.append(["mission execution", "", run.summary.duration_s, ""])
    bars = action_bars(run)
    for drone in run.drones:
        mine = [b for b in bars if b["drone"] == drone]
        if not mine:
            rows.append([drone, 0, 0.0, "no actions"])
            continue
        busy = sum(b["duration_s"] for b in mine)
        span = max(b["end_s"] for b in mine) - min(b["start_s"] for b in mine)
        longest = max(mine, key=lambda b: b["duration_s"])
        rows.append(
            [
                drone,
                len(mine),
                round(busy, 3),
                f"active {span:.2f} s; longest {longest['label']} {longest['duration_s']:.2f} s",
            ]
        )
    by_action: dict[str, list[float]] = {}
    for b in bars:
        by_action.setdefault(b["action"], []).append(b["duration_s"])
    for action, values in sorted(by_action.items()):
        rows.append(
            [
                f"  action: {action}",
                len(values),
                round(sum(values), 3),
                f"mean {sum(values) / len(values):.2f} s, max {max(values):.2f} s",
            ]
        )
    return Table(["what", "count", "seconds", "notes"], rows, "Durations")


def overview(run: RunData) -> Table:
    """The run in a few lines: mission, outcome, where each drone ran."""
    s = run.summary
    rows: list[list[Any]] = [
        ["mission", s.mission],
        ["mission id", s.mission_id],
        ["result", s.word],
        ["outcome", s.outcome],
        ["ok", s.ok],
        ["run folder", str(run.run_dir)],
    ]
    for drone in run.drones:
        result = s.drones[drone]
        where = result.host or "this machine"
        logs = (
            "logs here" if any(run.logs.get(drone, {}).values()) else "no logs (eamos logs fetch)"
        )
        rows.append([drone, f"{'ok' if result.ok else 'not ok'}; {where}; {logs}"])
    return Table(["", ""], rows, "Run")


# -- plots (matplotlib is imported only when drawing) ------------------------------------


def _colour(run: RunData, drone: str) -> str:
    return DRONE_COLOURS[run.drones.index(drone) % len(DRONE_COLOURS)]


def _axes(ax: Any, size: tuple[float, float]) -> tuple[Any, Any]:
    if ax is not None:
        return ax.figure, ax
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.add_subplot()


#: Gantt geometry, in points: label font size, a character's width, a row's height.
_GANTT_FONT_PT = 7.0
_GANTT_CHAR_PT = 0.6 * _GANTT_FONT_PT
_GANTT_ROW_PT = 0.7 * 0.9 * 72


@dataclass(frozen=True)
class GanttLabel:
    """Where one bar's label goes: its bar's index, the x centre, upright or turned."""

    bar: int
    x_s: float
    rotated: bool


def gantt_labels(bars: Sequence[dict[str, Any]], axis_width_pt: float) -> list[GanttLabel]:
    """Labels that fit: inside their bar, else turned upright, never over one another.

    ``bars`` are :func:`action_bars` rows; ``axis_width_pt`` is the plot's
    width.  A label that fits neither way is left out (the Durations table
    lists every action); a turned label needs its own strip of the row.
    """
    span = _span(bars)
    per_pt = span / axis_width_pt  # seconds per point
    out: list[GanttLabel] = []
    taken: dict[str, float] = {}  # per drone: where the last turned label's strip ends
    for i, b in enumerate(bars):
        width = max(b["duration_s"], 1e-3)
        centre = b["start_s"] + width / 2
        text_s = len(b["label"]) * _GANTT_CHAR_PT * per_pt
        if text_s <= width:
            out.append(GanttLabel(i, centre, False))
            continue
        strip = _GANTT_FONT_PT * 1.2 * per_pt
        fits_up = len(b["label"]) * _GANTT_CHAR_PT <= _GANTT_ROW_PT
        if fits_up and centre - strip / 2 >= taken.get(b["drone"], -float("inf")):
            out.append(GanttLabel(i, centre, True))
            taken[b["drone"]] = centre + strip / 2
    return out


def plot_gantt(run: RunData, ax: Any = None) -> Any:
    """Each drone's mission timeline: one bar per action, coloured by its result.

    Labels are placed by :func:`gantt_labels`, so they never overlap.
    """
    fig, ax = _axes(ax, (10, 1.2 + 0.9 * max(1, len(run.drones))))
    bars = action_bars(run)
    rows = {drone: row for row, drone in enumerate(run.drones)}
    for b in bars:
        ax.broken_barh(
            [(b["start_s"], max(b["duration_s"], 1e-3))],
            (rows[b["drone"]] - 0.35, 0.7),
            facecolors=RESULT_COLOURS.get(b["result"], "#999999"),
            edgecolor="white",
            linewidth=0.5,
        )
    # The axes take about 85 % of the figure's width.
    labels = gantt_labels(bars, fig.get_figwidth() * 72 * 0.85)
    for label in labels:
        b = bars[label.bar]
        ax.text(
            label.x_s,
            rows[b["drone"]],
            b["label"],
            ha="center",
            va="center",
            fontsize=_GANTT_FONT_PT,
            rotation=90 if label.rotated else 0,
            clip_on=True,
        )
    ax.set_yticks(range(len(run.drones)), run.drones)
    ax.invert_yaxis()
    hidden = len(bars) - len(labels)
    ax.set_xlabel(
        "seconds since the start trigger"
        + (f" ({hidden} short actions unlabelled: see Durations)" if hidden else "")
    )
    ax.set_title(f"{run.summary.mission}: actions per drone")
    from matplotlib.patches import Patch

    ax.legend(
        handles=[Patch(color=c, label=r) for r, c in RESULT_COLOURS.items()],
        loc="upper right",
        fontsize=7,
    )
    ax.grid(axis="x", alpha=0.3)
    return fig


def _span(bars: Sequence[dict[str, Any]]) -> float:
    if not bars:
        return 1.0
    return max(1e-3, max(b["end_s"] for b in bars) - min(b["start_s"] for b in bars))


def plot_xy(run: RunData, ax: Any = None) -> Any:
    """Trajectories seen from above (x, y), from each drone's ``adapter.log``."""
    fig, ax = _axes(ax, (5.5, 5))
    tracks = trajectories(run)
    homes = {d: home_of(run, d) for d in tracks}
    fleet_frame = any(h != (0.0, 0.0) for h in homes.values())
    for i, (drone, t) in enumerate(tracks.items()):
        if t["x"]:
            north, east = homes[drone]
            xs = [north + x for x in t["x"]]
            ys = [east + y for y in t["y"]]
            # Dashes differ per drone: drones flying the same shape would hide each other.
            ax.plot(
                ys,
                xs,
                marker=".",
                markersize=3,
                label=drone,
                color=_colour(run, drone),
                linestyle=_DASHES[i % len(_DASHES)],
            )
            ax.plot(ys[0], xs[0], "o", color=_colour(run, drone), alpha=0.5)
    if not any(t["x"] for t in tracks.values()):
        ax.text(
            0.5,
            0.5,
            "no adapter.log positions\n(eamos logs fetch)",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
    else:
        ax.legend(fontsize=8)
    # Seen from above: east to the right, north up.
    ax.set_xlabel("y, east (m)")
    ax.set_ylabel("x, north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    frame = "fleet frame" if fleet_frame else "each drone's local frame"
    ax.set_title(f"trajectories (x, y; {frame})")
    ax.grid(alpha=0.3)
    return fig


def plot_z(run: RunData, ax: Any = None) -> Any:
    """Altitude over time per drone."""
    fig, ax = _axes(ax, (10, 3))
    tracks = trajectories(run)
    for drone, t in tracks.items():
        if t["t"]:
            ax.plot(t["t"], t["z"], label=drone, color=_colour(run, drone))
    if any(t["t"] for t in tracks.values()):
        ax.legend(fontsize=8)
    ax.set_xlabel("seconds since the start trigger")
    ax.set_ylabel("z (m)")
    ax.set_title("altitude")
    ax.grid(alpha=0.3)
    return fig


def figure_png(fig: Any, dpi: int = 110) -> bytes:
    """A figure as PNG bytes (no display needed)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


# -- the HTML page ------------------------------------------------------------------------------

_CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 72em; color: #222; }
table.eamos { border-collapse: collapse; margin: 1em 0; }
table.eamos caption { text-align: left; font-weight: bold; padding: 0.3em 0; }
table.eamos td, table.eamos th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }
table.eamos th { background: #f3f3f3; }
img { max-width: 100%; }
.bad { color: #b00; font-weight: bold; }
"""


def html_page(run: RunData) -> str:
    """The report as one self-contained HTML page (plots embedded as PNG)."""
    import matplotlib  # a dependency of eamos: imported only when drawing (it is slow to load)

    matplotlib.use("Agg", force=False)  # no display needed; figures are Figure objects anyway
    images = []
    for title, fig in (
        ("Mission timeline", plot_gantt(run)),
        ("Trajectories", plot_xy(run)),
        ("Altitude", plot_z(run)),
    ):
        data = base64.b64encode(figure_png(fig)).decode("ascii")
        images.append(
            f"<h2>{html.escape(title)}</h2>"
            f'<img alt="{html.escape(title)}" src="data:image/png;base64,{data}">'
        )
    s = run.summary
    status = (
        s.word
        if s.ok
        else f'<span class="bad">{html.escape(s.word)}: {html.escape(s.detail)}</span>'
    )
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>EAMOS run {html.escape(s.mission)}</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>EAMOS run: {html.escape(s.mission)} ({status})</h1>",
        overview(run)._repr_html_(),
        table7(run)._repr_html_(),
        durations(run)._repr_html_(),
        *images,
        "</body></html>",
    ]
    return "\n".join(parts) + "\n"


def write_html(run_dir: Path | str, out: Path | str | None = None) -> Path:
    """Write ``html_page`` of ``run_dir`` to ``out`` (default ``RUN_DIR/report.html``)."""
    run = load_run(run_dir)
    path = Path(out) if out is not None else run.run_dir / "report.html"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html_page(run), encoding="utf-8")
    return path


__all__ = [
    "GanttLabel",
    "ReportError",
    "RunData",
    "Table",
    "action_bars",
    "durations",
    "figure_png",
    "gantt_labels",
    "home_of",
    "html_page",
    "load_run",
    "mismatch_reason",
    "overview",
    "plot_gantt",
    "plot_xy",
    "plot_z",
    "table7",
    "trajectories",
    "write_html",
]
