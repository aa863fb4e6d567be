"""Pictures of a check (``eamos check --svg OUT.svg``): tracks from above, altitude over time.

One panel per run with a finding (or the first run when there is none): on the
left every drone's track seen from above (east to the right, north up, the
geofence dashed), on the right each drone's altitude over time; separation and
geofence findings are marked where they happen (a red ring, the drones and the
time).  Plain SVG written by hand: no plotting library.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from html import escape

from .findings import CheckReport, Finding
from .tracks import Track

COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf")
PANEL_W, PANEL_H, PAD = 900, 340, 40
MAP_W = 380


def _scale(lo: float, hi: float, out_lo: float, out_hi: float) -> Callable[[float], float]:
    span = (hi - lo) or 1.0
    return lambda v: out_lo + (v - lo) / span * (out_hi - out_lo)


def _panel(
    y0: float,
    title: str,
    tracks: Mapping[str, Track],
    findings: list[Finding],
    fence: list[tuple[float, float]],
) -> list[str]:
    out = [f'<text x="{PAD}" y="{y0 + 20}" font-size="14">{escape(title)}</text>']
    pts = [p for t in tracks.values() for p in t.points]
    if not pts:
        return out
    norths = [p.north_m for p in pts] + [n for n, _ in fence]
    easts = [p.east_m for p in pts] + [e for _, e in fence]
    side = max(max(norths) - min(norths), max(easts) - min(easts), 1.0) * 1.1
    mid_n, mid_e = (max(norths) + min(norths)) / 2, (max(easts) + min(easts)) / 2
    top, size = y0 + 35, PANEL_H - 60
    sx = _scale(mid_e - side / 2, mid_e + side / 2, PAD, PAD + size)
    sy = _scale(mid_n - side / 2, mid_n + side / 2, top + size, top)
    out.append(
        f'<rect x="{PAD}" y="{top}" width="{size}" height="{size}" fill="none" stroke="#ccc"/>'
    )
    if fence:
        ring = " ".join(f"{sx(e):.1f},{sy(n):.1f}" for n, e in fence)
        out.append(f'<polygon points="{ring}" fill="none" stroke="#888" stroke-dasharray="4 3"/>')
    t_end = max(p.t_s for p in pts) or 1.0
    z_top = max(max(p.up_m for p in pts), 1.0) * 1.1
    ax0, ax1 = PAD + MAP_W + 60, PANEL_W - PAD
    tx = _scale(0.0, t_end, ax0, ax1)
    tz = _scale(0.0, z_top, top + size, top)
    out.append(
        f'<rect x="{ax0}" y="{top}" width="{ax1 - ax0}" height="{size}" fill="none" stroke="#ccc"/>'
        f'<text x="{ax0}" y="{top + size + 15}" font-size="11">0 s</text>'
        f'<text x="{ax1 - 50}" y="{top + size + 15}" font-size="11">{t_end:.1f} s</text>'
        f'<text x="{ax0 - 45}" y="{top + 10}" font-size="11">{z_top:.1f} m</text>'
    )
    for i, (drone, track) in enumerate(sorted(tracks.items())):
        colour = COLOURS[i % len(COLOURS)]
        above = " ".join(f"{sx(p.east_m):.1f},{sy(p.north_m):.1f}" for p in track.points)
        alt = " ".join(f"{tx(p.t_s):.1f},{tz(p.up_m):.1f}" for p in track.points)
        out.append(f'<polyline class="track" points="{above}" fill="none" stroke="{colour}"/>')
        out.append(f'<polyline class="altitude" points="{alt}" fill="none" stroke="{colour}"/>')
        out.append(
            f'<text x="{ax1 - 80}" y="{top + 15 + 14 * i}" font-size="11" fill="{colour}">'
            f"{escape(drone)}</text>"
        )
    for f in findings:
        if not f.positions or f.time_s is None:
            continue
        for _, (n, e, z) in f.positions:
            out.append(
                f'<circle class="finding" cx="{sx(e):.1f}" cy="{sy(n):.1f}" r="6" '
                f'fill="none" stroke="red" stroke-width="2"/>'
                f'<circle cx="{tx(f.time_s):.1f}" cy="{tz(z):.1f}" r="4" fill="none" '
                f'stroke="red"/>'
            )
        n, e, _ = f.positions[0][1]
        drones = " and ".join(d for d, _ in f.positions)
        out.append(
            f'<text x="{sx(e) + 8:.1f}" y="{sy(n) - 8:.1f}" font-size="11" fill="red">'
            f"{escape(f.check)}: {escape(drones)} at {f.time_s:.1f} s</text>"
        )
    return out


def svg(report: CheckReport) -> str:
    """The SVG document of a report (see module doc)."""
    fence = [(float(p[0]), float(p[1])) for p in report.settings.get("geofence_m", [])]
    panels: list[str] = []
    for k, (branch, tracks) in enumerate(report.tracks):
        mine = [f for f in report.findings if f.branch == branch]
        title = f"run [{branch}]: " + (
            "; ".join(sorted({f.check for f in mine})) if mine else "no finding"
        )
        panels += _panel(k * PANEL_H, title, tracks, mine, fence)
    height = max(len(report.tracks), 1) * PANEL_H
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{PANEL_W}" height="{height}" '
        f'font-family="sans-serif">\n'
        f"<title>{escape(report.mission)}: eamos check</title>\n" + "\n".join(panels) + "\n</svg>\n"
    )


__all__ = ["svg"]
