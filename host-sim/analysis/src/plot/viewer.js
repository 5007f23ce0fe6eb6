(function () {
  "use strict";
  function axis(lo, hi, max) {
    if (!(isFinite(lo) && isFinite(hi)) || hi < lo) { lo = 0; hi = 1; }
    if (hi - lo <= 1e-12 * Math.max(Math.abs(lo), Math.abs(hi), 1e-300)) { var w = lo === 0 ? 1 : 0.1 * Math.abs(lo); lo -= w; hi += w; }
    var mag = Math.pow(10, Math.floor(Math.log10((hi - lo) / max))), step = mag;
    search: for (var d = 0; d < 4; d++, mag *= 10) {
      var ms = [1, 2, 5];
      for (var i = 0; i < 3; i++) {
        step = ms[i] * mag;
        if (Math.ceil(hi / step) - Math.floor(lo / step) + 1 <= max) break search;
      }
    }
    return { lo: Math.floor(lo / step) * step, hi: Math.ceil(hi / step) * step, step: step };
  }
  function label(v, step) {
    if (Math.abs(v) < step * 1e-9) return "0";
    if (Math.max(Math.abs(v), step) >= 1e6 || step < 1e-4) return v.toExponential(Math.max(0, Math.min(6, Math.floor(Math.log10(Math.max(Math.abs(v), step))) - Math.floor(Math.log10(step))))).replace("e+", "e");
    return v.toFixed(Math.max(0, -Math.floor(Math.log10(step) + 1e-9)));
  }
  function lower(a, v) { var l = 0, h = a.length; while (l < h) { var m = (l + h) >> 1; if (a[m] < v) l = m + 1; else h = m; } return l; }
  function view(fig) {
    var d = JSON.parse(fig.querySelector("script.iv-data").textContent);
    // values arrive as integer steps (x as differences): back to numbers, once
    d.series.forEach(function (s) {
      s.levels.forEach(function (lv) {
        var acc = 0, x = new Float64Array(lv.x.length);
        for (var i = 0; i < x.length; i++) { acc += lv.x[i]; x[i] = d.xq[0] + acc * d.xq[1]; }
        lv.x = x;
        var dec = function (a) { return a.map(function (k) { return k === null ? null : s.yq[0] + k * s.yq[1]; }); };
        lv.lo = dec(lv.lo);
        if (lv.hi) lv.hi = dec(lv.hi);
      });
    });
    var svg = fig.querySelector("svg.plot");
    var W = d.w, H = d.h, L = 70, R = 14, T = 30, B = 46, pw = W - L - R, ph = H - T - B;
    var dpr = window.devicePixelRatio || 1;
    var cv = document.createElement("canvas");
    cv.className = "iv-canvas"; cv.width = W * dpr; cv.height = H * dpr;
    cv.style.width = W + "px"; cv.style.height = H + "px"; cv.style.cursor = "crosshair";
    var help = document.createElement("div");
    help.className = "iv-help";
    help.textContent = "wheel: zoom in time · drag: pan · shift+drag: zoom to a box · double-click: whole log";
    var g = cv.getContext("2d");
    var v = { x0: d.x0, x1: d.x1, y: null }, box = null, drag = null;
    function pick(s) {
      for (var k = 0; k < s.levels.length; k++) {
        var lv = s.levels[k], a = lower(lv.x, v.x0), b = lower(lv.x, v.x1);
        if (b - a <= 2 * pw || k === s.levels.length - 1) return { lv: lv, a: Math.max(0, a - 1), b: Math.min(lv.x.length, b + 1) };
      }
    }
    function draw() {
      var parts = d.series.map(pick), ylo = Infinity, yhi = -Infinity, n = 0;
      parts.forEach(function (p) {
        var hi = p.lv.hi || p.lv.lo;
        for (var i = p.a; i < p.b; i++) { if (p.lv.lo[i] !== null) { ylo = Math.min(ylo, p.lv.lo[i]); yhi = Math.max(yhi, hi[i]); } }
      });
      var pad = 0.03 * (yhi - ylo);
      var ax = axis(v.x0, v.x1, Math.max(4, Math.min(11, Math.floor(W / 80))));
      var ay = v.y ? axis(v.y[0], v.y[1], 8) : axis(ylo - pad, yhi + pad, Math.max(4, Math.min(9, Math.floor(H / 45))));
      var xr = v.y ? [v.x0, v.x1] : [v.x0, v.x1];
      var px = function (x) { return L + (x - xr[0]) / (xr[1] - xr[0]) * pw; };
      var py = function (y) { return T + ph - (y - ay.lo) / (ay.hi - ay.lo) * ph; };
      g.setTransform(dpr, 0, 0, dpr, 0, 0);
      g.fillStyle = "#fff"; g.fillRect(0, 0, W, H);
      g.font = "11px sans-serif"; g.fillStyle = "#000"; g.strokeStyle = "#ddd"; g.lineWidth = 1;
      g.textAlign = "center";
      for (var t = Math.ceil(v.x0 / ax.step) * ax.step; t <= v.x1 + 1e-9 * ax.step; t += ax.step) {
        var X = Math.round(px(t)) + 0.5;
        g.beginPath(); g.moveTo(X, T); g.lineTo(X, T + ph); g.stroke();
        g.fillText(label(t, ax.step), X, T + ph + 14);
      }
      g.textAlign = "right";
      for (var k = Math.round(ay.lo / ay.step); k <= Math.round(ay.hi / ay.step); k++) {
        var Y = Math.round(py(k * ay.step)) + 0.5;
        g.beginPath(); g.moveTo(L, Y); g.lineTo(L + pw, Y); g.stroke();
        g.fillText(label(k * ay.step, ay.step), L - 6, Y + 4);
      }
      g.strokeStyle = "#444"; g.strokeRect(L + 0.5, T + 0.5, pw, ph);
      g.textAlign = "center"; g.font = "13px sans-serif";
      g.fillText(d.xl, L + pw / 2, H - 8);
      g.save(); g.translate(14, T + ph / 2); g.rotate(-Math.PI / 2); g.fillText(d.yl, 0, 0); g.restore();
      g.font = "14px sans-serif"; g.fillText(d.title, W / 2, 18);
      g.save(); g.beginPath(); g.rect(L, T, pw, ph); g.clip();
      parts.forEach(function (p, si) {
        var s = d.series[si], lv = p.lv, hi = lv.hi || lv.lo;
        g.strokeStyle = s.colour; g.lineWidth = 1; g.beginPath();
        var up = false;
        for (var i = p.a; i < p.b; i++) {
          if (lv.lo[i] === null) { up = false; continue; }
          var X = px(lv.x[i]);
          if (!up) { g.moveTo(X, py(lv.lo[i])); up = true; } else g.lineTo(X, py(lv.lo[i]));
          if (hi !== lv.lo) g.lineTo(X, py(hi[i]));
          n++;
        }
        g.stroke();
      });
      if (box) { g.strokeStyle = "#06c"; g.setLineDash([4, 3]); g.strokeRect(box[0], box[1], box[2] - box[0], box[3] - box[1]); g.setLineDash([]); }
      g.restore();
      g.font = "11px sans-serif"; g.textAlign = "left";
      d.series.forEach(function (s, si) {
        var y = T + 14 + 15 * si;
        g.fillStyle = s.colour; g.fillRect(L + pw - 130, y - 6, 16, 3);
        g.fillStyle = "#000"; g.fillText(s.name, L + pw - 108, y);
      });
      fig.setAttribute("data-iv-drawn", String(n));
      fig.setAttribute("data-iv-range", label(v.x0, ax.step / 100) + " " + label(v.x1, ax.step / 100));
      v.unpx = function (X, Y) { return [xr[0] + (X - L) / pw * (xr[1] - xr[0]), ay.lo + (T + ph - Y) / ph * (ay.hi - ay.lo)]; };
    }
    function at(e) { var r = cv.getBoundingClientRect(); return [e.clientX - r.left, e.clientY - r.top]; }
    cv.addEventListener("wheel", function (e) {
      e.preventDefault();
      var c = v.unpx(at(e)[0], 0)[0], f = e.deltaY > 0 ? 1.25 : 0.8;
      var x0 = c - (c - v.x0) * f, x1 = c + (v.x1 - c) * f;
      v.x0 = Math.max(d.x0, x0); v.x1 = Math.min(d.x1, x1); draw();
    }, { passive: false });
    cv.addEventListener("mousedown", function (e) { drag = { p: at(e), x0: v.x0, x1: v.x1, shift: e.shiftKey }; });
    window.addEventListener("mousemove", function (e) {
      if (!drag) return;
      var p = at(e);
      if (drag.shift) { box = [Math.min(drag.p[0], p[0]), Math.min(drag.p[1], p[1]), Math.max(drag.p[0], p[0]), Math.max(drag.p[1], p[1])]; }
      else {
        var dx = (p[0] - drag.p[0]) / pw * (drag.x1 - drag.x0), w = drag.x1 - drag.x0;
        var x0 = Math.min(Math.max(d.x0, drag.x0 - dx), d.x1 - w);
        v.x0 = x0; v.x1 = x0 + w;
      }
      draw();
    });
    window.addEventListener("mouseup", function () {
      if (drag && drag.shift && box && box[2] - box[0] > 3 && box[3] - box[1] > 3) {
        var a = v.unpx(box[0], box[3]), b = v.unpx(box[2], box[1]);
        v.x0 = a[0]; v.x1 = b[0]; v.y = [a[1], b[1]];
      }
      drag = null; box = null; draw();
    });
    cv.addEventListener("dblclick", function () { v = { x0: d.x0, x1: d.x1, y: null }; draw(); });
    fig.insertBefore(cv, svg);
    fig.appendChild(help);
    draw();
    svg.style.display = "none";
    fig.setAttribute("data-iv", "ready");
  }
  var figs = document.querySelectorAll("figure.iv");
  for (var i = 0; i < figs.length; i++) { try { view(figs[i]); } catch (e) { figs[i].setAttribute("data-iv", "error: " + e); } }
})();
