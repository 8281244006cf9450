"""An offline 3D viewer of a session's trajectories: inlined JavaScript on a 2D canvas.

No library and no network: the data (positions rounded to the millimetre, fields thinned
evenly so each trial stays under a sample budget) and a small orbit viewer are written
into the page. Drag to turn, wheel to zoom, shift-drag (or right-drag) to pan.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from kisscal.report.htmlkit import Html, esc
from kisscal.report.markers import Dense


def thin_step(n_markers: int, n_fields: int, max_samples: int) -> int:
    """Keep every ``step``-th field so that markers x fields stays under ``max_samples``.

    Examples
    --------
    >>> thin_step(15, 200, 4000), thin_step(31, 221, 4000)
    (1, 2)
    """
    return max(1, math.ceil(n_markers * n_fields / max(max_samples, 1)))


def trial_data(
    name: str, dense: Dense, rate_hz: float, segments: Sequence[tuple[str, str]], max_samples: int
) -> dict[str, Any]:
    """One trial for the viewer: thinned positions in whole mm, gaps as ``null``."""
    step = thin_step(len(dense.labels), dense.n_fields, max_samples)
    xyz = np.round(dense.xyz_mm[:, ::step]).astype(object)
    xyz[~np.isfinite(dense.xyz_mm[:, ::step])] = None
    index = {n: k for k, n in enumerate(dense.labels)}
    pairs = [[index[a], index[b]] for a, b in segments if a in index and b in index]
    return {
        "name": name,
        "rate": rate_hz / step,
        "step": step,
        "labels": list(dense.labels),
        "frames": int(xyz.shape[1]),
        "xyz": [[None if v is None else int(v) for v in m.ravel()] for m in xyz],
        "segments": pairs,
    }


def viewer_data(
    trials: Mapping[str, dict[str, Any]], cameras: Mapping[str, Sequence[float]]
) -> dict[str, Any]:
    """Everything the viewer script reads: trials (each with its :func:`default_view`) and
    camera centres (mm)."""
    cams = [
        {"id": c, "xyz": [round(float(v)) for v in xyz]}
        for c, xyz in cameras.items()
        if xyz is not None and len(xyz) == 3 and all(math.isfinite(float(v)) for v in xyz)
    ]
    centres = np.array([c["xyz"] for c in cams], dtype=float).reshape(-1, 3)
    views = [{**t, "view": default_view(t["xyz"], centres)} for t in trials.values()]
    return {"trials": views, "cameras": cams}


#: Least radius of the default view (mm): a trial of one still marker is not a dot.
MIN_VIEW_RADIUS_MM = 400.0


def default_view(xyz: Sequence[Sequence[float | None]], cameras_mm: np.ndarray) -> dict:
    """The sphere the viewer first shows: centred on the trial's samples, wide enough for
    every sample and every camera (the script draws any point inside it on screen).

    Examples
    --------
    >>> v = default_view([[0, 0, 1000, 100, 0, 1000]], np.array([[3000.0, 4000.0, 1000.0]]))
    >>> v["centre"], v["radius"] >= 0.5 * 5000
    ([50.0, 0.0, 1000.0], True)
    """
    flat = np.array([np.nan if v is None else v for m in xyz for v in m], dtype=float)
    points = flat.reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    if not len(points):
        points = np.array([[-1000.0, -1000.0, 0.0], [1000.0, 1000.0, 1000.0]])
    centre = (points.min(axis=0) + points.max(axis=0)) / 2
    reach = np.vstack([points, cameras_mm]) - centre
    radius = max(MIN_VIEW_RADIUS_MM, float(np.linalg.norm(reach, axis=1).max()) * 1.05)
    return {"centre": [round(float(c), 1) for c in centre], "radius": round(radius, 1)}


def viewer_html(data: Mapping[str, Any]) -> Html:
    """The viewer's markup, its data as JSON and its script, ready to inline."""
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    options = "".join(
        f'<option value="{k}">{esc(t["name"])}</option>' for k, t in enumerate(data["trials"])
    )
    return Html(
        '<div class="viewer" id="kc-viewer">'
        '<div class="viewer-bar">'
        f'<label>trial <select id="kc-trial">{options}</select></label>'
        '<button type="button" id="kc-play">&#9654; play</button>'
        '<input type="range" id="kc-frame" min="0" max="0" value="0" aria-label="field">'
        '<span id="kc-time" class="mono"></span>'
        '<label><input type="checkbox" id="kc-trails" checked> trails</label>'
        '<label><input type="checkbox" id="kc-labels" checked> labels</label>'
        '<label><input type="checkbox" id="kc-cams" checked> cameras</label>'
        '<button type="button" data-view="persp">3D</button>'
        '<button type="button" data-view="top">top (X-Y)</button>'
        '<button type="button" data-view="side">side (X-Z)</button>'
        '<button type="button" data-view="front">front (Y-Z)</button>'
        "</div>"
        '<canvas id="kc-canvas" width="1000" height="560"></canvas>'
        '<p class="note" id="kc-info"></p>'
        "<noscript><p>The 3D viewer needs JavaScript.</p></noscript>"
        "</div>"
        f'<script type="application/json" id="kc-data">{payload}</script>'
        f"<script>{VIEWER_JS}</script>"
    )


VIEWER_JS = r"""
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("kc-data").textContent);
  var canvas = document.getElementById("kc-canvas");
  if (!canvas || !data.trials.length) { return; }
  var ctx = canvas.getContext("2d");
  var el = function (id) { return document.getElementById(id); };
  var state = { trial: 0, frame: 0, playing: false, yaw: -0.6, pitch: 0.45, zoom: 1,
                panX: 0, panY: 0, ortho: false, last: 0 };
  var trial, centre, radius;

  function colour(k, n) { return "hsl(" + Math.round(360 * k / Math.max(n, 1)) + ",70%,42%)"; }
  function point(m, f) {
    var a = trial.xyz[m], i = 3 * f;
    if (a[i] === null || a[i] === undefined) { return null; }
    return [a[i], a[i + 1], a[i + 2]];
  }
  function bounds() {
    if (trial.view) { centre = trial.view.centre; radius = trial.view.radius; return; }
    var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    trial.xyz.forEach(function (a) {
      for (var i = 0; i < a.length; i += 3) {
        if (a[i] === null) { continue; }
        for (var d = 0; d < 3; d++) {
          lo[d] = Math.min(lo[d], a[i + d]); hi[d] = Math.max(hi[d], a[i + d]);
        }
      }
    });
    if (!isFinite(lo[0])) { lo = [-1000, -1000, 0]; hi = [1000, 1000, 1000]; }
    centre = [0, 1, 2].map(function (d) { return (lo[d] + hi[d]) / 2; });
    radius = Math.max(400, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
  }
  function project(p) {
    var x = p[0] - centre[0], y = p[1] - centre[1], z = p[2] - centre[2];
    var cy = Math.cos(state.yaw), sy = Math.sin(state.yaw);
    var cp = Math.cos(state.pitch), sp = Math.sin(state.pitch);
    var u = cy * x + sy * y;                 // to the right on screen
    var w = -sy * x + cy * y;                // away from the viewer (before pitch)
    var v = cp * z + sp * w;                 // up on screen (pitch: looking down)
    var depth = cp * w - sp * z;             // away from the viewer
    // A point within radius of the centre comes at most 6/5 times nearer in perspective:
    // 1.2 / 2.6 of the canvas from its middle, on screen at zoom 1.
    var dist = 6 * radius, scale = Math.min(canvas.width, canvas.height) / (2.6 * radius);
    var s = state.ortho ? scale : scale * dist / Math.max(dist + depth, 0.1 * dist);
    s *= state.zoom;
    return [canvas.width / 2 + state.panX + u * s, canvas.height / 2 + state.panY - v * s, depth];
  }
  function line(a, b, stroke, width) {
    var p = project(a), q = project(b);
    ctx.strokeStyle = stroke; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
  }
  function floor() {
    var step = 500, n = Math.ceil(1.5 * radius / step);
    var x0 = Math.round(centre[0] / step) * step, y0 = Math.round(centre[1] / step) * step;
    for (var k = -n; k <= n; k++) {
      line([x0 + k * step, y0 - n * step, 0], [x0 + k * step, y0 + n * step, 0], "#e3e3e3", 1);
      line([x0 - n * step, y0 + k * step, 0], [x0 + n * step, y0 + k * step, 0], "#e3e3e3", 1);
    }
    var axes = [["X", [500, 0, 0], "#c0392b"], ["Y", [0, 500, 0], "#27ae60"],
                ["Z", [0, 0, 500], "#2c6fbb"]];
    axes.forEach(function (a) {
      line([0, 0, 0], a[1], a[2], 2);
      var p = project(a[1]); ctx.fillStyle = a[2]; ctx.fillText(a[0], p[0] + 3, p[1] - 3);
    });
  }
  function cameras() {
    if (!el("kc-cams").checked) { return; }
    ctx.fillStyle = "#444";
    data.cameras.forEach(function (c) {
      var p = project(c.xyz);
      ctx.fillRect(p[0] - 4, p[1] - 4, 8, 8);
      ctx.fillText(c.id, p[0] + 6, p[1] - 6);
    });
  }
  function trails() {
    if (!el("kc-trails").checked) { return; }
    var n = trial.labels.length;
    for (var m = 0; m < n; m++) {
      ctx.strokeStyle = colour(m, n); ctx.globalAlpha = 0.35; ctx.lineWidth = 1;
      ctx.beginPath();
      var open = false;
      for (var f = 0; f < trial.frames; f++) {
        var p = point(m, f);
        if (!p) { open = false; continue; }
        var q = project(p);
        if (open) { ctx.lineTo(q[0], q[1]); } else { ctx.moveTo(q[0], q[1]); open = true; }
      }
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
  }
  function markers() {
    var f = state.frame, n = trial.labels.length, shown = [], k;
    trial.segments.forEach(function (s) {
      var a = point(s[0], f), b = point(s[1], f);
      if (a && b) { line(a, b, "#555", 2); }
    });
    for (k = 0; k < n; k++) {
      var p = point(k, f);
      if (p) { shown.push([project(p), k]); }
    }
    shown.sort(function (a, b) { return b[0][2] - a[0][2]; });
    shown.forEach(function (s) {
      ctx.fillStyle = colour(s[1], n);
      ctx.beginPath(); ctx.arc(s[0][0], s[0][1], 4.5, 0, 2 * Math.PI); ctx.fill();
      if (el("kc-labels").checked) {
        ctx.fillStyle = "#222"; ctx.fillText(trial.labels[s[1]], s[0][0] + 6, s[0][1] + 4);
      }
    });
    return shown.length;
  }
  function draw() {
    var w = canvas.clientWidth;
    if (w > 0 && canvas.width !== Math.round(w)) { canvas.width = Math.round(w); }
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    ctx.font = "12px sans-serif";
    floor(); cameras(); trails();
    var visible = markers();
    var t = state.frame / trial.rate;
    el("kc-time").textContent = "field " + state.frame * trial.step + "  t = " + t.toFixed(2) +
      " s  (" + visible + "/" + trial.labels.length + " markers)";
  }
  function selectTrial(k) {
    state.trial = k; trial = data.trials[k]; state.frame = 0;
    state.panX = 0; state.panY = 0; state.zoom = 1;
    bounds();
    var slider = el("kc-frame");
    slider.max = Math.max(trial.frames - 1, 0); slider.value = 0;
    el("kc-info").textContent = trial.labels.length + " trajectories, " + trial.frames +
      " frames" + (trial.step > 1 ? " (every " + trial.step + "th field shown)" : "") +
      ". Drag to turn, wheel to zoom, shift-drag or right-drag to pan.";
    draw();
  }
  function tick(now) {
    if (!state.playing) { return; }
    if (now - state.last >= 1000 / trial.rate) {
      state.last = now;
      state.frame = (state.frame + 1) % Math.max(trial.frames, 1);
      el("kc-frame").value = state.frame;
      draw();
    }
    window.requestAnimationFrame(tick);
  }
  el("kc-trial").addEventListener("change", function (e) { selectTrial(+e.target.value); });
  el("kc-frame").addEventListener("input", function (e) { state.frame = +e.target.value; draw(); });
  el("kc-play").addEventListener("click", function () {
    state.playing = !state.playing;
    el("kc-play").innerHTML = state.playing ? "&#10074;&#10074; pause" : "&#9654; play";
    if (state.playing) { window.requestAnimationFrame(tick); }
  });
  ["kc-trails", "kc-labels", "kc-cams"].forEach(function (id) {
    el(id).addEventListener("change", draw);
  });
  var views = { persp: [-0.6, 0.45, false], top: [0, Math.PI / 2, true],
                side: [0, 0, true], front: [Math.PI / 2, 0, true] };
  Array.prototype.forEach.call(document.querySelectorAll("#kc-viewer [data-view]"), function (b) {
    b.addEventListener("click", function () {
      var v = views[b.getAttribute("data-view")];
      state.yaw = v[0]; state.pitch = v[1]; state.ortho = v[2];
      state.panX = 0; state.panY = 0; state.zoom = 1; draw();
    });
  });
  var drag = null;
  canvas.addEventListener("contextmenu", function (e) { e.preventDefault(); });
  canvas.addEventListener("mousedown", function (e) {
    drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 };
  });
  window.addEventListener("mouseup", function () { drag = null; });
  window.addEventListener("mousemove", function (e) {
    if (!drag) { return; }
    var dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.pan) { state.panX += dx; state.panY += dy; } else {
      state.yaw -= dx * 0.01;
      state.pitch = Math.max(-1.5, Math.min(1.5, state.pitch + dy * 0.01));
      state.ortho = false;
    }
    draw();
  });
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    state.zoom = Math.max(0.2, Math.min(20, state.zoom * Math.exp(-e.deltaY * 0.001)));
    draw();
  }, { passive: false });
  window.addEventListener("resize", draw);
  selectTrial(0);
})();
"""
