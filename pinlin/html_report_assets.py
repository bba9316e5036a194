"""The style sheet and the script of the HTML report (:mod:`pinlin.html_report`), inline.

The script (plain ES2015, no library) reads the JSON data block ``#pinlin-data`` and draws the
selected mode's stick figure on the canvas ``#figure`` with an orthographic 3-D projection of
its own: the view starts in the mode's plane of largest displacement
(:func:`pinlin.figure_view.best_view`) and turns with the mouse (drag) or the arrow keys. The
figure steps through the stored phases of one cycle (about 1.6 s per cycle); ``#play``
pauses it. ``#mode`` (or a click on a table row or an eigenvalue) selects the mode,
``#amplitude`` one of the stored amplitudes. Every frame drawn is a configuration computed in
Python (nothing is interpolated), so a mechanism's loops stay closed at every phase.
"""

STYLE = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px;
       padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 13px; }
th, td { border-bottom: 1px solid #ddd; padding: 3px 8px; text-align: right; }
th { background: #f3f3f3; } td.text, th.text { text-align: left; }
#mode-table tbody tr { cursor: pointer; }
#mode-table tbody tr.selected { background: #dbe9f8; }
#mode-table tbody tr.undrawn { color: #888; cursor: default; }
.viewer { display: flex; gap: 1.5em; flex-wrap: wrap; align-items: flex-start; }
#figure { border: 1px solid #ccc; background: #fff; cursor: grab; }
.controls { margin: 0.4em 0; display: flex; gap: 1em; align-items: center; flex-wrap: wrap; }
.eig circle { fill: #1f77b4; fill-opacity: 0.75; cursor: pointer; }
.eig circle.selected { fill: #d62728; fill-opacity: 1; }
.eig text { font-size: 10px; fill: #555; }
.note { color: #555; font-size: 13px; }
img.plot { max-width: 100%; border: 1px solid #eee; }
"""

SCRIPT = r"""
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("pinlin-data").textContent);
  var canvas = document.getElementById("figure");
  var ctx = canvas.getContext("2d");
  var select = document.getElementById("mode");
  var slider = document.getElementById("amplitude");
  var ampText = document.getElementById("amplitude-value");
  var playButton = document.getElementById("play");
  var state = { mode: 0, level: 0, frame: 0, playing: true, view: null, last: 0, acc: 0 };

  function matmul(a, b) {
    var c = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
    for (var i = 0; i < 3; i++)
      for (var j = 0; j < 3; j++)
        for (var k = 0; k < 3; k++) c[i][j] += a[i][k] * b[k][j];
    return c;
  }
  function rotation(axis, angle) {          // about screen axis 0 (right) or 1 (up)
    var c = Math.cos(angle), s = Math.sin(angle);
    return axis === 0 ? [[1, 0, 0], [0, c, -s], [0, s, c]]
                      : [[c, 0, s], [0, 1, 0], [-s, 0, c]];
  }
  function current() { return data.modes[state.mode]; }
  function frames() { return current().frames[state.level]; }

  function fit() {                          // centre and scale over every frame of the level
    var lo = [1e300, 1e300, 1e300], hi = [-1e300, -1e300, -1e300];
    var all = frames().concat([data.rest]);
    for (var f = 0; f < all.length; f++)
      for (var p = 0; p < all[f].length; p += 3)
        for (var k = 0; k < 3; k++) {
          lo[k] = Math.min(lo[k], all[f][p + k]); hi[k] = Math.max(hi[k], all[f][p + k]);
        }
    var r = 0, centre = [0, 0, 0];
    for (k = 0; k < 3; k++) { centre[k] = (lo[k] + hi[k]) / 2; r += Math.pow(hi[k] - lo[k], 2); }
    return { centre: centre, scale: 0.9 * Math.min(canvas.width, canvas.height) /
             Math.max(Math.sqrt(r), 1e-3) };
  }
  function project(pts, fitted) {
    var out = [], v = state.view, c = fitted.centre;
    for (var p = 0; p < pts.length; p += 3) {
      var d = [pts[p] - c[0], pts[p + 1] - c[1], pts[p + 2] - c[2]];
      var x = v[0][0] * d[0] + v[0][1] * d[1] + v[0][2] * d[2];
      var y = v[1][0] * d[0] + v[1][1] * d[1] + v[1][2] * d[2];
      out.push([canvas.width / 2 + fitted.scale * x, canvas.height / 2 - fitted.scale * y]);
    }
    return out;
  }
  function drawFigure(xy, color, width) {
    ctx.strokeStyle = color; ctx.fillStyle = color; ctx.lineWidth = width;
    ctx.lineCap = "round";
    data.links.forEach(function (l) {
      ctx.beginPath(); ctx.moveTo(xy[l[0]][0], xy[l[0]][1]);
      ctx.lineTo(xy[l[1]][0], xy[l[1]][1]); ctx.stroke();
    });
    xy.slice(0, data.kinds.length).forEach(function (p, i) {
      ctx.beginPath();
      if (data.kinds[i] === "world") {
        ctx.moveTo(p[0], p[1] - 6); ctx.lineTo(p[0] - 6, p[1] + 5); ctx.lineTo(p[0] + 6, p[1] + 5);
        ctx.closePath(); ctx.fillStyle = "#000"; ctx.fill(); ctx.fillStyle = color;
      } else { ctx.arc(p[0], p[1], width + 1.5, 0, 2 * Math.PI); ctx.fill(); }
    });
    ctx.lineWidth = 1.5;
    data.closures.forEach(function (c) {
      ctx.beginPath(); ctx.arc(xy[c[0]][0], xy[c[0]][1], 7, 0, 2 * Math.PI); ctx.stroke();
    });
  }
  function drawTriads(xy) {                 // frames of the joints a mode turns in place
    var colors = ["#d62728", "#2ca02c", "#1f77b4"], first = data.kinds.length;
    ctx.lineWidth = 1.5;
    current().triads.forEach(function (k, t) {
      for (var a = 0; a < 3; a++) {
        var tip = xy[first + 3 * t + a];
        ctx.strokeStyle = colors[a];
        ctx.beginPath(); ctx.moveTo(xy[k][0], xy[k][1]); ctx.lineTo(tip[0], tip[1]); ctx.stroke();
      }
    });
  }
  function drawAxes() {                     // world x, y, z in the lower left corner
    var o = [34, canvas.height - 34], names = ["x", "y", "z"];
    var colors = ["#d62728", "#2ca02c", "#1f77b4"];
    ctx.lineWidth = 2; ctx.font = "12px sans-serif";
    for (var k = 0; k < 3; k++) {
      var x = 24 * state.view[0][k], y = -24 * state.view[1][k];
      ctx.strokeStyle = colors[k]; ctx.fillStyle = colors[k];
      ctx.beginPath(); ctx.moveTo(o[0], o[1]); ctx.lineTo(o[0] + x, o[1] + y); ctx.stroke();
      ctx.fillText(names[k], o[0] + 1.2 * x - 3, o[1] + 1.2 * y + 4);
    }
  }
  function draw() {
    var mode = current(), fitted = fit();
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    drawFigure(project(data.rest, fitted), "#aaa", 4);
    var moving = project(frames()[state.frame], fitted);
    drawFigure(moving, "#1f77b4", 2);
    drawTriads(moving);
    drawAxes();
    ctx.fillStyle = "#222"; ctx.font = "13px sans-serif";
    ctx.fillText(mode.label, 10, 18);
    var phase = Math.round(360 * state.frame / frames().length);
    ctx.fillText("a = " + mode.amplitudes[state.level].toPrecision(3) + " " + mode.unit +
                 " on " + mode.coordinate + ", phase " + phase + " deg", 10, 36);
  }
  function selectMode(k) {
    state.mode = k; state.view = current().view.map(function (r) { return r.slice(); });
    slider.max = String(current().amplitudes.length - 1);
    state.level = current().unit_level; slider.value = String(state.level);
    state.frame = Math.min(state.frame, frames().length - 1);
    select.value = String(k);
    var number = String(current().number);
    document.querySelectorAll("[data-mode]").forEach(function (el) {
      el.classList.toggle("selected", el.getAttribute("data-mode") === number);
    });
    updateAmplitude(); draw();
  }
  function updateAmplitude() {
    var mode = current();
    ampText.textContent = mode.amplitudes[state.level].toPrecision(3) + " " + mode.unit + " (" +
      mode.factors[state.level] + " x the default)";
  }
  function tick(t) {
    if (state.playing && state.last) {
      state.acc += t - state.last;
      var step = 1600 / frames().length;
      if (state.acc >= step) {
        state.frame = (state.frame + Math.floor(state.acc / step)) % frames().length;
        state.acc %= step; draw();
      }
    }
    state.last = t;
    window.requestAnimationFrame(tick);
  }

  select.addEventListener("change", function () { selectMode(Number(select.value)); });
  slider.addEventListener("input", function () {
    state.level = Number(slider.value); updateAmplitude(); draw();
  });
  playButton.addEventListener("click", function () {
    state.playing = !state.playing; playButton.textContent = state.playing ? "Pause" : "Play";
  });
  document.getElementById("reset-view").addEventListener("click", function () {
    state.view = current().view.map(function (r) { return r.slice(); }); draw();
  });
  document.querySelectorAll("[data-mode]").forEach(function (el) {
    el.addEventListener("click", function () {
      var number = Number(el.getAttribute("data-mode"));
      for (var k = 0; k < data.modes.length; k++)
        if (data.modes[k].number === number) { selectMode(k); return; }
    });
  });
  var drag = null;
  canvas.addEventListener("mousedown", function (e) { drag = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", function () { drag = null; });
  window.addEventListener("mousemove", function (e) {
    if (!drag) return;
    var dx = e.clientX - drag[0], dy = e.clientY - drag[1];
    drag = [e.clientX, e.clientY];
    state.view = matmul(matmul(rotation(0, dy * 0.01), rotation(1, dx * 0.01)), state.view);
    draw();
  });
  canvas.tabIndex = 0;
  canvas.addEventListener("keydown", function (e) {
    var turns = { ArrowLeft: [1, -0.1], ArrowRight: [1, 0.1],
                  ArrowUp: [0, -0.1], ArrowDown: [0, 0.1] };
    if (!turns[e.key]) return;
    state.view = matmul(rotation(turns[e.key][0], turns[e.key][1]), state.view);
    e.preventDefault(); draw();
  });
  if (data.modes.length) { selectMode(data.start); window.requestAnimationFrame(tick); }
})();
"""
