"""A self-contained interactive trajectory view: inline SVG + a few lines of inline JS.

Pan (drag), zoom (wheel, double-click resets) and hover for the nearest slot's details. No
external script, style or font: the report stays one file that works offline.
"""

from __future__ import annotations

import html
import itertools
import json
from typing import Any

import numpy as np

from skymule.report.figures import sensor_colours
from skymule.report.inputs import RunData, hover_segments
from skymule.report.style import NEUTRAL

#: Script shared by every interactive view of a report (reads the JSON in #slot-data).
SCRIPT = """
(function () {
  const data = JSON.parse(document.getElementById("slot-data").textContent);
  function fmt(v, d) { return (v === null || v === undefined) ? "-" : Number(v).toFixed(d); }
  document.querySelectorAll("svg.traj").forEach(function (svg) {
    const run = data[svg.dataset.run];
    const tip = svg.parentNode.querySelector(".tip");
    const mark = svg.querySelector(".cursor");
    const home = [svg.viewBox.baseVal.x, svg.viewBox.baseVal.y,
                  svg.viewBox.baseVal.width, svg.viewBox.baseVal.height];
    let drag = null;
    function pt(e) {
      const p = svg.createSVGPoint(); p.x = e.clientX; p.y = e.clientY;
      return p.matrixTransform(svg.getScreenCTM().inverse());
    }
    svg.addEventListener("wheel", function (e) {
      e.preventDefault();
      const k = e.deltaY > 0 ? 1.2 : 1 / 1.2, p = pt(e), vb = svg.viewBox.baseVal;
      vb.x = p.x - (p.x - vb.x) * k; vb.y = p.y - (p.y - vb.y) * k;
      vb.width *= k; vb.height *= k;
    }, { passive: false });
    svg.addEventListener("mousedown", function (e) { drag = pt(e); });
    window.addEventListener("mouseup", function () { drag = null; });
    svg.addEventListener("dblclick", function () {
      const vb = svg.viewBox.baseVal;
      vb.x = home[0]; vb.y = home[1]; vb.width = home[2]; vb.height = home[3];
    });
    svg.addEventListener("mousemove", function (e) {
      const p = pt(e), vb = svg.viewBox.baseVal;
      if (drag) { vb.x -= p.x - drag.x; vb.y -= p.y - drag.y; return; }
      let best = 0, bestD = Infinity;
      for (let i = 0; i < run.x.length; i++) {
        const dx = run.x[i] - p.x, dy = -run.y[i] - p.y, d = dx * dx + dy * dy;
        if (d < bestD) { bestD = d; best = i; }
      }
      mark.setAttribute("cx", run.x[best]); mark.setAttribute("cy", -run.y[best]);
      mark.setAttribute("visibility", "visible");
      let left = run.sensors.map(function (n) { return n + " " + fmt(run.remaining[n][best], 1); });
      tip.textContent = "t = " + fmt(run.t[best], 0) + " s | (" + fmt(run.x[best], 0) + ", " +
        fmt(run.y[best], 0) + ") m | serving " + (run.served[best] || "none") + " at " +
        fmt(run.rate[best], 2) + " Mbit/s" + (run.hover[best] ? " (hovering)" : "") +
        " | left [Mbit]: " + left.join(", ");
    });
  });
})();
"""


def _rounded(values: Any, digits: int) -> list[float | None]:
    array = np.round(np.asarray(values, float), digits)
    return [None if not np.isfinite(v) else float(v) for v in array]


def slot_payload(run: RunData) -> dict[str, Any]:
    """Columnar per-slot data the script reads (rounded to keep the file small)."""
    slots = run.slots
    return {
        "t": _rounded(slots["t_s"], 2),
        "x": _rounded(slots["x_m"], 1),
        "y": _rounded(slots["y_m"], 1),
        "served": [str(s) for s in slots["served"]],
        "rate": _rounded(slots.get("rate_mbps", np.zeros(len(slots))), 3),
        "hover": [int(h) for h in slots.get("hovering", np.zeros(len(slots), int))],
        "sensors": run.sensor_names,
        "remaining": {
            n: _rounded(slots[f"remaining_mbit_{n}"], 2)
            for n in run.sensor_names
            if f"remaining_mbit_{n}" in slots
        },
    }


def payload_script(runs: list[RunData]) -> str:
    """The ``<script type="application/json" id="slot-data">`` element for all runs."""
    text = json.dumps({str(i): slot_payload(r) for i, r in enumerate(runs)}, separators=(",", ":"))
    safe = text.replace("</", "<\\/")  # never close the script element early
    return f'<script type="application/json" id="slot-data">{safe}</script>'


def _points(xy: np.ndarray) -> str:
    return " ".join(f"{x:.1f},{-y:.1f}" for x, y in xy)


def trajectory_svg(run: RunData, index: int, width_px: int = 560) -> str:
    """Inline SVG of one run's path (north up), towers, geofence and hover points."""
    site, slots = run.site, run.slots
    colours = sensor_colours(run.sensor_names)
    xy = slots[["x_m", "y_m"]].to_numpy(float)
    parts = [xy]
    if site.fence_xy_m is not None:
        parts.append(site.fence_xy_m)
    if site.known_sensors:
        parts.append(site.sensor_xyz_m[site.known_sensors, :2])
    parts.append(site.home_xy_m[None, :])
    every = np.vstack(parts)
    lo, hi = every.min(axis=0), every.max(axis=0)
    margin = 0.06 * float(max(hi - lo)) + 10.0
    span = hi - lo + 2 * margin
    view = f"{lo[0] - margin:.1f} {-hi[1] - margin:.1f} {span[0]:.1f} {span[1]:.1f}"
    stroke = 0.004 * float(max(span))
    body = []
    if site.fence_xy_m is not None:
        body.append(
            f'<polygon class="fence" points="{_points(site.fence_xy_m)}" fill="#f2f2f2" '
            f'stroke="#555" stroke-dasharray="{4 * stroke:.1f}" stroke-width="{stroke:.2f}"/>'
        )
    served = slots["served"].to_numpy(str)
    cuts = np.flatnonzero(np.r_[True, served[1:] != served[:-1], True])
    for start, end in itertools.pairwise(cuts):
        piece = xy[start : min(end + 1, len(xy))]
        colour = colours.get(served[start], NEUTRAL)
        body.append(
            f'<polyline class="path" points="{_points(piece)}" fill="none" stroke="{colour}" '
            f'stroke-width="{1.5 * stroke:.2f}"><title>{html.escape(served[start] or "none")}'
            "</title></polyline>"
        )
    for hover in hover_segments(slots, run.slot_s):
        body.append(
            f'<circle class="hover" cx="{hover.x_m:.1f}" cy="{-hover.y_m:.1f}" '
            f'r="{(3 + 0.1 * hover.duration_s) * stroke:.1f}" fill="none" '
            f'stroke="{colours.get(hover.sensor, NEUTRAL)}" stroke-width="{stroke:.2f}">'
            f"<title>hover {html.escape(hover.sensor)}: {hover.duration_s:.0f} s from "
            f"t = {hover.start_s:.0f} s, {hover.downloaded_mbit:.1f} Mbit</title></circle>"
        )
    for i in site.known_sensors:
        name = site.sensor_names[i]
        x_m, y_m = site.sensor_xyz_m[i, :2]
        size = 4 * stroke
        triangle = _points(
            np.array([[x_m - size, y_m - size], [x_m + size, y_m - size], [x_m, y_m + size]])
        )
        body.append(
            f'<polygon class="tower" points="{triangle}" fill="{colours.get(name, NEUTRAL)}" '
            f'stroke="#000" stroke-width="{0.5 * stroke:.2f}"><title>{html.escape(name)}</title>'
            f'</polygon><text x="{x_m + size:.1f}" y="{-y_m - size:.1f}" '
            f'font-size="{10 * stroke:.1f}">{html.escape(name)}</text>'
        )
    hx, hy = site.home_xy_m
    body.append(
        f'<rect class="home" x="{hx - 2 * stroke:.1f}" y="{-hy - 2 * stroke:.1f}" '
        f'width="{4 * stroke:.1f}" height="{4 * stroke:.1f}" fill="#000"><title>home</title></rect>'
        f'<circle class="cursor" r="{3 * stroke:.1f}" fill="none" stroke="#000" '
        f'stroke-width="{stroke:.2f}" visibility="hidden"/>'
    )
    height_px = int(width_px * span[1] / span[0]) if span[0] > 0 else width_px
    height_px = max(200, min(height_px, 2 * width_px))
    return (
        f'<svg class="traj" data-run="{index}" viewBox="{view}" width="{width_px}" '
        f'height="{height_px}" xmlns="http://www.w3.org/2000/svg" role="img" '
        f'aria-label="interactive trajectory of {html.escape(run.label)}">'
        + "".join(body)
        + "</svg>"
    )
