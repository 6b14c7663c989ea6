// jointspace view: the page's own code. Reads the summary (JSON) and the typed arrays the command wrote into the
// page, and draws the layer view (Canvas 2D), the 3D view (WebGL), the tables and the motor plots (uPlot).
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const errors = [];
  function fail(message) {
    errors.push(message);
    const list = $("errors");
    list.hidden = false;
    const li = document.createElement("li");
    li.textContent = message;
    list.appendChild(li);
  }
  window.addEventListener("error", (e) => fail(String(e.message)));
  window.addEventListener("unhandledrejection", (e) => fail(String(e.reason)));

  const S = JSON.parse($("summary").textContent);
  const E = S.estimate;

  function array(name) {
    const el = $("d-" + name);
    if (!el) return null;
    const text = atob(el.textContent);
    const bytes = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    const types = { f32: Float32Array, u16: Uint16Array, u32: Uint32Array, u8: Uint8Array };
    return new types[el.dataset.type](bytes.buffer);
  }

  // ---- the segments ------------------------------------------------------------------------------------------
  const EXTRUDING = 1, SLOWED = 2, JUMP = 4;
  const CAUSE = { atSpeed: 0, accel: 1, other: 2, bedTurn: 3, refused: 4, firstMotor: 5 };
  const D = (function () {
    const to = array("to"), jumps = array("jump-from"), flags = array("flags");
    const n = flags.length;
    const from = new Float32Array(3 * n);
    let j = 0;
    for (let i = 0; i < n; i++) {
      const src = flags[i] & JUMP ? jumps : to;
      const at = flags[i] & JUMP ? 3 * j++ : 3 * (i - 1);
      for (let k = 0; k < 3; k++) from[3 * i + k] = i === 0 && !(flags[i] & JUMP) ? to[k] : src[at + k];
    }
    const speed16 = array("speed");
    const speed = new Float32Array(n);
    for (let i = 0; i < n; i++) speed[i] = (speed16[i] / 65535) * S.scales.speed;
    const motors = S.motors.map((m, index) => {
      const decode = (name, full) => {
        const raw = array("motor" + index + "-" + name), out = new Float32Array(n);
        for (let i = 0; i < n; i++) out[i] = (raw[i] / 65535) * (full || 0);
        return out;
      };
      return { speed: decode("speed", S.scales.motor_speed[index]), accel: decode("accel", S.scales.motor_accel[index]) };
    });
    return {
      n, from, to, flags, speed, motors,
      start: array("start"), duration: array("duration"), requested: array("requested"),
      cause: array("cause"), line: array("line"),
    };
  })();
  const refusedFirst = S.segments.kept;
  const layerOf = new Uint32Array(D.n);
  S.layers.forEach((l, i) => layerOf.fill(i, l.first, l.first + l.count));
  S.refused.forEach((r, k) => (layerOf[refusedFirst + k] = r.layer));

  // ---- colours -----------------------------------------------------------------------------------------------
  const CAUSE_COLOURS = ["#43a047", "#64b5f6", "#9e9e9e", "#6a1b9a", "#ff1744",
    "#ff9800", "#d500f9", "#795548", "#00bcd4", "#fdd835", "#3949ab", "#f06292"];
  const RAMP = [[48, 18, 140], [33, 145, 200], [60, 190, 90], [240, 200, 40], [215, 40, 30]];
  function ramp(t) {
    t = Math.max(0, Math.min(1, t)) * (RAMP.length - 1);
    const i = Math.min(RAMP.length - 2, Math.floor(t)), f = t - i;
    return RAMP[i].map((c, k) => Math.round(c + (RAMP[i + 1][k] - c) * f));
  }
  function hex(c) {
    return [1, 3, 5].map((i) => parseInt(c.slice(i, i + 2), 16));
  }
  const limitOf = (motor, kind) => {
    const l = S.limits.motor_limits.find((m) => m.index === motor);
    return l ? (kind === "speed" ? l.max_velocity : l.max_accel) : null;
  };
  const modes = [
    { id: "cause", label: "the limit that holds each move" },
    { id: "speed", label: "speed (mm/s)" },
    { id: "slowdown", label: "speed against requested" },
    { id: "time", label: "print time" },
  ];
  S.motors.forEach((m, i) => {
    for (const kind of ["speed", "accel"]) {
      const limit = limitOf(i, kind);
      const word = kind === "speed" ? "speed" : "acceleration";
      modes.push({ id: "motor" + i + "-" + kind, motor: i, kind, limit,
        label: m.name + " " + word + (limit ? " against its limit" : " (" + m.unit + (kind === "speed" ? "/s" : "/s²") + ")") });
    }
  });
  function colourOf(mode, i) {
    if (D.cause[i] === CAUSE.refused) return hex(CAUSE_COLOURS[CAUSE.refused]);
    switch (mode.id) {
      case "cause": return hex(CAUSE_COLOURS[D.cause[i] % CAUSE_COLOURS.length]);
      case "speed": return ramp(D.speed[i] / S.scales.speed);
      case "slowdown": return ramp(D.requested[i] > 0 ? D.speed[i] / D.requested[i] : 1);
      case "time": return ramp(D.start[i] / Math.max(E.total, 1e-9));
    }
    const values = D.motors[mode.motor][mode.kind];
    const full = mode.limit || (mode.kind === "speed" ? S.scales.motor_speed : S.scales.motor_accel)[mode.motor] || 1;
    return ramp(values[i] / full);
  }
  function legend(mode) {
    const list = $("legend");
    list.textContent = "";
    const entry = (rgb, text, cause) => {
      const li = document.createElement("li");
      li.dataset.rgb = rgb.join(",");
      if (cause !== undefined) li.dataset.cause = String(cause);
      const swatch = document.createElement("span");
      swatch.style.background = "rgb(" + rgb.join(",") + ")";
      li.append(swatch, text);
      list.appendChild(li);
    };
    if (mode.id === "cause") {
      const present = new Set(D.cause);
      S.limits.labels.forEach((label, c) => {
        if (present.has(c)) entry(hex(CAUSE_COLOURS[c % CAUSE_COLOURS.length]), label, c);
      });
      $("scale-note").textContent = "Each move in the colour of what holds it below its requested speed " +
        "(a motor limit names it where the move reaches the cap that limit puts on it).";
      return;
    }
    const scale = {
      speed: [0, S.scales.speed, "mm/s"], slowdown: [0, 1, "of the requested speed"],
      time: [0, E.total, "s"],
    }[mode.id] || [0, mode.limit || (mode.kind === "speed" ? S.scales.motor_speed : S.scales.motor_accel)[mode.motor],
      mode.limit ? "(the limit)" : S.motors[mode.motor].unit + (mode.kind === "speed" ? "/s" : "/s²")];
    for (let k = 0; k <= 4; k++) entry(ramp(k / 4), fmt(scale[0] + (scale[1] - scale[0]) * k / 4) + " " + scale[2]);
    entry(hex(CAUSE_COLOURS[CAUSE.refused]), "refused", CAUSE.refused);
    $("scale-note").textContent = mode.limit ? "Red: at the motor's limit." : "";
  }
  function fmt(v) {
    if (v === null || v === undefined || !isFinite(v)) return String(v);
    const a = Math.abs(v);
    return a >= 100 ? v.toFixed(0) : a >= 10 ? v.toFixed(1) : a >= 1 ? v.toFixed(2) : v.toPrecision(3);
  }
  function hms(s) {
    if (!isFinite(s)) return String(s);
    if (Math.abs(s) < 60) return s.toFixed(1) + "s";
    const w = Math.round(Math.abs(s)), h = Math.floor(w / 3600), m = Math.floor(w / 60) % 60, r = w % 60;
    const two = (x) => String(x).padStart(2, "0");
    return (s < 0 ? "-" : "") + (h ? h + "h " + two(m) + "m " : m + "m ") + two(r) + "s";
  }

  // ---- the numbers -------------------------------------------------------------------------------------------
  function row(table, cells, id, value) {
    const tr = document.createElement("tr");
    cells.forEach((c, k) => {
      const td = document.createElement("td");
      td.textContent = c;
      if (k > 0) td.className = "n";
      tr.appendChild(td);
    });
    if (id) {
      tr.id = id;
      tr.dataset.value = String(value);
    }
    table.appendChild(tr);
    return tr;
  }
  function numbers() {
    const t = $("times");
    row(t, ["planned (jointspace)", hms(E.total)], "total", E.total);
    row(t, ["Klipper's planner without the motor limits", hms(E.without_motor_limits)], "without-limits",
      E.without_motor_limits);
    if (E.klipper_rule !== undefined) row(t, ["Klipper's own rule (whole moves slowed near the centre)", hms(E.klipper_rule)],
      "klipper-rule", E.klipper_rule);
    if (E.klipper_exit_time !== undefined) row(t, ["Klipper logs at the end (batch)", hms(E.klipper_exit_time)],
      "klipper-exit", E.klipper_exit_time);
    row(t, ["the slicer's estimate", E.slicer === null ? "none" : hms(E.slicer)], "slicer", E.slicer);
    row(t, ["layers", String(E.layers.length)], "layer-count", E.layers.length);
    row(t, ["segments drawn / planned", S.segments.kept + " / " + S.segments.planned], "segments", S.segments.kept);
    const l = $("limits");
    if (!E.limits.length) row(l, ["none configured: Klipper's planner alone", ""]);
    E.limits.forEach((m) => {
      const v = (x) => (x === null ? "-" : fmt(x));
      row(l, [m.motor + " (v " + v(m.max_velocity) + ", a " + v(m.max_accel) + ") alone adds", hms(m.lost)],
        "limit-" + m.motor, m.lost);
    });
    if (E.limits.length) row(l, ["all together add", hms(E.total - E.without_motor_limits)], "limits-add",
      E.total - E.without_motor_limits);
    S.motors.forEach((m, i) => {
      for (const kind of ["speed", "accel"]) {
        const values = array("series" + i + "-" + kind);
        if (!values) continue;
        const peak = values.reduce((a, b) => Math.max(a, b), 0), limit = limitOf(i, kind);
        const unit = m.unit + (kind === "speed" ? "/s" : "/s²");
        row(l, [m.name + " peak " + (kind === "speed" ? "speed" : "acceleration") + (limit ? " (limit " + fmt(limit) + ")" : ""),
          fmt(peak) + " " + unit], "peak-" + m.name + "-" + kind, peak);
      }
    });
    const f = $("features");
    E.features.forEach((p) => row(f, [p.name === null ? "(before the first marker)" : p.name, hms(p.time),
      p.lost ? "+" + hms(p.lost) : ""], null));
    $("slowed-total").textContent = E.slowed_total + " moves slowed below a quarter of their speed" +
      (E.slowed.length < E.slowed_total ? " (the first " + E.slowed.length + " lines listed)" : "");
    $("slowed-total").dataset.value = String(E.slowed_total);
    E.slowed.slice(0, 500).forEach((s) => listLine($("slowed"), s.line,
      "line " + s.line + ": " + fmt(s.allowed) + " of " + fmt(s.requested) + " mm/s, " + why(s.line)));
    $("refused-total").textContent = S.refused_total ? S.refused_total + " moves the machine refused" +
      " (the plan goes on from where the machine stays)" : "none";
    $("refused-total").dataset.value = String(S.refused_total);
    S.refused.slice(0, 500).forEach((r) => listLine($("refused"), r.line, "line " + r.line + ": " + r.reason));
  }
  function listLine(list, line, text) {
    const li = document.createElement("li");
    li.className = "link";
    li.textContent = text;
    li.addEventListener("click", () => focusLine(line));
    list.appendChild(li);
  }
  // The drawn segment of a G-code line (the one with the most telling cause): segments are in line order (a
  // merged one carries its first line), refused moves after them.
  function segmentOfLine(line) {
    let lo = 0, hi = refusedFirst;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (D.line[mid] < line) lo = mid + 1; else hi = mid; }
    let best;
    for (let i = lo; i < refusedFirst && D.line[i] === line; i++) if (best === undefined || D.cause[i] > D.cause[best]) best = i;
    for (let k = 0; k < S.refused.length; k++) if (S.refused[k].line === line) best = refusedFirst + k;
    if (best === undefined && lo > 0 && lo <= refusedFirst) best = lo - 1;
    return best;
  }
  function why(line) {
    const i = segmentOfLine(line);
    if (i === undefined) return "not drawn";
    let text = S.limits.labels[D.cause[i]];
    const c = S.map && S.map.outline && S.map.outline.circle;
    if (S.machine === "polar" && c) {
      const x = (D.from[3 * i] + D.to[3 * i]) / 2 - c.centre[0], y = (D.from[3 * i + 1] + D.to[3 * i + 1]) / 2 - c.centre[1];
      text += ", " + fmt(Math.hypot(x, y)) + " mm from the bed's centre";
    }
    return text;
  }

  // ---- the layer view ----------------------------------------------------------------------------------------
  const canvas = $("layer-canvas"), ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  const state = { mode: modes[0], layer: 0, map: "none", travel: false, scale: 1, cx: 0, cy: 0, focus: -1, view: "layer" };
  function fit() {
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    for (let i = 0; i < refusedFirst; i++) {
      if (!(D.flags[i] & EXTRUDING)) continue;
      for (const p of [D.from, D.to]) {
        x0 = Math.min(x0, p[3 * i]); x1 = Math.max(x1, p[3 * i]);
        y0 = Math.min(y0, p[3 * i + 1]); y1 = Math.max(y1, p[3 * i + 1]);
      }
    }
    if (!isFinite(x0)) { x0 = -100; x1 = 100; y0 = -100; y1 = 100; }
    state.cx = (x0 + x1) / 2; state.cy = (y0 + y1) / 2;
    state.scale = 0.9 * Math.min(W / Math.max(x1 - x0, 1), H / Math.max(y1 - y0, 1));
  }
  const px = (x) => W / 2 + (x - state.cx) * state.scale;
  const py = (y) => H / 2 - (y - state.cy) * state.scale;
  const mapImage = {};
  function mapCanvas(id) {
    if (mapImage[id] !== undefined) return mapImage[id];
    const m = S.map;
    const raw = m.nx ? array(id === "reach" ? "map-reach" : "map-" + id) : null;
    if (!raw) return (mapImage[id] = null);
    // Resolution layers: 16-bit fractions of the layer's largest value, 65535 where unreachable.
    const layer = m.layers.find((l) => l.id === id);
    const values = id === "reach" ? raw : Array.from(raw, (v) => (v === 65535 ? NaN : (v / 65534) * layer.max));
    const c = document.createElement("canvas");
    c.width = m.nx; c.height = m.ny;
    const g = c.getContext("2d"), img = g.createImageData(m.nx, m.ny);
    let lo = Infinity, hi = -Infinity;
    if (id !== "reach") values.forEach((v) => { if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } });
    const reach = [[200, 230, 201], [224, 224, 224], [255, 204, 188], [248, 187, 208], [209, 196, 233], [187, 222, 251]];
    for (let iy = 0; iy < m.ny; iy++) for (let ix = 0; ix < m.nx; ix++) {
      const v = values[iy * m.nx + ix], o = 4 * ((m.ny - 1 - iy) * m.nx + ix);
      let rgb = id === "reach" ? reach[v % reach.length] : isFinite(v) ? ramp(Math.log(v / lo) / Math.log(hi / lo || 2)) : [224, 224, 224];
      if (id !== "reach") rgb = rgb.map((x) => Math.round(255 - (255 - x) * 0.45));
      img.data.set([rgb[0], rgb[1], rgb[2], 255], o);
    }
    g.putImageData(img, 0, 0);
    c.range = [lo, hi];
    return (mapImage[id] = c);
  }
  function drawMap() {
    const m = S.map;
    if (state.map === "none" || !m.nx) return;
    const img = mapCanvas(state.map);
    if (!img) return;
    ctx.imageSmoothingEnabled = false;
    const x0 = px(m.x_min), y0 = py(m.y_min + m.ny * m.cell);
    ctx.drawImage(img, x0, y0, m.nx * m.cell * state.scale, m.ny * m.cell * state.scale);
    ctx.strokeStyle = "#37474f"; ctx.lineWidth = 1.5; ctx.beginPath();
    if (m.outline.circle) ctx.arc(px(m.outline.circle.centre[0]), py(m.outline.circle.centre[1]),
      m.outline.circle.radius * state.scale, 0, 2 * Math.PI);
    else { const r = m.outline.rectangle; ctx.rect(px(r.min[0]), py(r.max[1]), (r.max[0] - r.min[0]) * state.scale, (r.max[1] - r.min[1]) * state.scale); }
    ctx.stroke();
  }
  function segmentsOf(layer) {
    const l = S.layers[layer], list = [];
    if (l) for (let i = l.first; i < l.first + l.count; i++) list.push(i);
    for (let k = 0; k < S.refused.length; k++) if (S.refused[k].layer === layer) list.push(refusedFirst + k);
    return list;
  }
  const shown = (i) => state.travel || D.flags[i] & EXTRUDING || D.cause[i] > CAUSE.other;
  function drawLayer() {
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, W, H);
    drawMap();
    ctx.lineCap = "round";
    if (state.layer > 0) {
      ctx.strokeStyle = "rgba(120,120,120,0.25)"; ctx.lineWidth = 1; ctx.beginPath();
      for (const i of segmentsOf(state.layer - 1)) if (D.flags[i] & EXTRUDING) line(i);
      ctx.stroke();
    }
    const groups = new Map();
    for (const i of segmentsOf(state.layer)) {
      if (!shown(i)) continue;
      const key = colourOf(state.mode, i).join(",") + (D.flags[i] & EXTRUDING ? "" : "t");
      if (!groups.has(key)) groups.set(key, []);
      groups.get(key).push(i);
    }
    const flagged = [];
    for (const [key, list] of groups) {
      const travel = key.endsWith("t");
      ctx.strokeStyle = "rgb(" + key.replace("t", "") + ")";
      ctx.lineWidth = travel ? 0.8 : Math.max(1.5, Math.min(4, 0.45 * state.scale));
      ctx.setLineDash(travel ? [3, 3] : []);
      ctx.beginPath();
      for (const i of list) { line(i); if (D.cause[i] >= CAUSE.bedTurn) flagged.push(i); }
      ctx.stroke();
    }
    ctx.setLineDash([]);
    for (const i of flagged) marker(i);
    if (state.focus >= 0 && layerOf[state.focus] === state.layer) {
      ctx.strokeStyle = "rgb(" + colourOf(state.mode, state.focus).join(",") + ")";
      ctx.lineWidth = 8; ctx.beginPath(); line(state.focus); ctx.stroke();
    }
  }
  function line(i) {
    ctx.moveTo(px(D.from[3 * i]), py(D.from[3 * i + 1]));
    ctx.lineTo(px(D.to[3 * i]), py(D.to[3 * i + 1]));
  }
  function marker(i) {
    ctx.fillStyle = "rgb(" + colourOf(state.mode, i).join(",") + ")";
    ctx.beginPath();
    ctx.arc(px(D.to[3 * i]), py(D.to[3 * i + 1]), D.cause[i] === CAUSE.refused ? 5 : 3, 0, 2 * Math.PI);
    ctx.fill();
  }
  function nearest(mx, my) {
    let best = -1, bestD = 8 * 8;
    for (const i of segmentsOf(state.layer)) {
      if (!shown(i)) continue;
      const ax = px(D.from[3 * i]), ay = py(D.from[3 * i + 1]), bx = px(D.to[3 * i]), by = py(D.to[3 * i + 1]);
      const dx = bx - ax, dy = by - ay, len = dx * dx + dy * dy;
      const t = len > 0 ? Math.max(0, Math.min(1, ((mx - ax) * dx + (my - ay) * dy) / len)) : 0;
      const d = (ax + t * dx - mx) ** 2 + (ay + t * dy - my) ** 2;
      if (d < bestD) { bestD = d; best = i; }
    }
    return best;
  }
  function describe(i) {
    if (D.cause[i] === CAUSE.refused) {
      const r = S.refused[i - refusedFirst];
      return ["line " + r.line + ": refused: " + r.reason];
    }
    const parts = ["line " + D.line[i] + (D.flags[i] & EXTRUDING ? "" : " (travel)"),
      fmt(D.speed[i]) + " of " + fmt(D.requested[i]) + " mm/s: " + S.limits.labels[D.cause[i]],
      "at " + hms(D.start[i]) + " for " + fmt(D.duration[i]) + " s"];
    S.motors.forEach((m, k) => {
      const ls = limitOf(k, "speed"), la = limitOf(k, "accel"), u = m.unit;
      parts.push(m.name + ": " + fmt(D.motors[k].speed[i]) + (ls ? " of " + fmt(ls) : "") + " " + u + "/s, " +
        fmt(D.motors[k].accel[i]) + (la ? " of " + fmt(la) : "") + " " + u + "/s²");
    });
    return parts;
  }
  canvas.addEventListener("mousemove", (e) => {
    const r = canvas.getBoundingClientRect(), i = nearest(e.clientX - r.left, e.clientY - r.top);
    const tip = $("tip");
    tip.hidden = i < 0;
    if (i >= 0) {
      tip.textContent = "";
      describe(i).forEach((text, k) => { if (k) tip.appendChild(document.createElement("br")); tip.append(text); });
      tip.style.left = Math.min(e.clientX - r.left + 14, W - 360) + "px";
      tip.style.top = (e.clientY - r.top + 14) + "px";
    }
  });
  canvas.addEventListener("mouseleave", () => ($("tip").hidden = true));
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const r = canvas.getBoundingClientRect(), mx = e.clientX - r.left, my = e.clientY - r.top;
    const x = state.cx + (mx - W / 2) / state.scale, y = state.cy - (my - H / 2) / state.scale;
    state.scale *= Math.exp(-e.deltaY * 0.0015);
    state.cx = x - (mx - W / 2) / state.scale; state.cy = y + (my - H / 2) / state.scale;
    drawLayer();
  }, { passive: false });
  let drag = null;
  canvas.addEventListener("mousedown", (e) => (drag = [e.clientX, e.clientY]));
  window.addEventListener("mouseup", () => (drag = null));
  window.addEventListener("mousemove", (e) => {
    if (!drag || state.view !== "layer") return;
    state.cx -= (e.clientX - drag[0]) / state.scale; state.cy += (e.clientY - drag[1]) / state.scale;
    drag = [e.clientX, e.clientY];
    drawLayer();
  });

  // ---- the 3D view (WebGL, no library: a line list and an orbiting camera) -----------------------------------
  const gl3 = { gl: null, count: [], yaw: -0.6, pitch: 0.9, dist: 1, centre: [0, 0, 0] };
  function initGl() {
    const c = $("gl-canvas");
    const gl = c.getContext("webgl", { antialias: true });
    if (!gl) { $("gl-note").textContent = "This browser gives the page no WebGL: the 3D view is not available."; return; }
    const shader = (type, src) => { const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s); return s; };
    const prog = gl.createProgram();
    gl.attachShader(prog, shader(gl.VERTEX_SHADER,
      "attribute vec3 p; attribute vec3 c; uniform mat4 m; varying vec3 v; void main(){gl_Position=m*vec4(p,1.0);v=c;}"));
    gl.attachShader(prog, shader(gl.FRAGMENT_SHADER,
      "precision mediump float; varying vec3 v; void main(){gl_FragColor=vec4(v,1.0);}"));
    gl.linkProgram(prog);
    gl.useProgram(prog);
    const keep = [];
    for (let i = 0; i < D.n; i++) if (D.flags[i] & EXTRUDING || D.cause[i] > CAUSE.other) keep.push(i);
    const pos = new Float32Array(keep.length * 6);
    keep.forEach((i, k) => { pos.set(D.from.subarray(3 * i, 3 * i + 3), 6 * k); pos.set(D.to.subarray(3 * i, 3 * i + 3), 6 * k + 3); });
    const buffer = (data, name, size, type, norm) => {
      const b = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      const at = gl.getAttribLocation(prog, name); gl.enableVertexAttribArray(at); gl.vertexAttribPointer(at, size, type, norm, 0, 0);
      return b;
    };
    buffer(pos, "p", 3, gl.FLOAT, false);
    gl3.colours = buffer(new Uint8Array(keep.length * 6), "c", 3, gl.UNSIGNED_BYTE, true);
    gl3.keep = keep;
    gl3.count = S.layers.map((_, l) => { let k = 0; while (k < keep.length && layerOf[keep[k]] <= l) k++; return k; });
    let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let k = 0; k < pos.length; k++) { lo[k % 3] = Math.min(lo[k % 3], pos[k]); hi[k % 3] = Math.max(hi[k % 3], pos[k]); }
    if (!keep.length) { lo = [0, 0, 0]; hi = [1, 1, 1]; }
    gl3.centre = lo.map((v, k) => (v + hi[k]) / 2);
    gl3.dist = 2.2 * Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1);
    gl3.gl = gl; gl3.prog = prog;
    gl.enable(gl.DEPTH_TEST);
    let spin = null;
    c.addEventListener("mousedown", (e) => (spin = [e.clientX, e.clientY]));
    window.addEventListener("mouseup", () => (spin = null));
    window.addEventListener("mousemove", (e) => {
      if (!spin) return;
      gl3.yaw += (e.clientX - spin[0]) * 0.01;
      gl3.pitch = Math.max(0.05, Math.min(3.09, gl3.pitch - (e.clientY - spin[1]) * 0.01));
      spin = [e.clientX, e.clientY];
      draw3d();
    });
    c.addEventListener("wheel", (e) => { e.preventDefault(); gl3.dist *= Math.exp(e.deltaY * 0.0015); draw3d(); }, { passive: false });
  }
  function colour3d() {
    const gl = gl3.gl;
    if (!gl) return;
    const col = new Uint8Array(gl3.keep.length * 6);
    gl3.keep.forEach((i, k) => { const c = colourOf(state.mode, i); col.set(c, 6 * k); col.set(c, 6 * k + 3); });
    gl.bindBuffer(gl.ARRAY_BUFFER, gl3.colours);
    gl.bufferData(gl.ARRAY_BUFFER, col, gl.STATIC_DRAW);
  }
  function draw3d() {
    const gl = gl3.gl;
    if (!gl) return;
    const c = gl3.centre, d = gl3.dist;
    const eye = [c[0] + d * Math.sin(gl3.pitch) * Math.cos(gl3.yaw), c[1] + d * Math.sin(gl3.pitch) * Math.sin(gl3.yaw),
      c[2] + d * Math.cos(gl3.pitch)];
    const m = multiply(perspective(0.8, W / H, d / 100, d * 10), lookAt(eye, c, [0, 0, 1]));
    gl.uniformMatrix4fv(gl.getUniformLocation(gl3.prog, "m"), false, m);
    gl.viewport(0, 0, W, H);
    gl.clearColor(1, 1, 1, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.drawArrays(gl.LINES, 0, 2 * (gl3.count[state.layer] || 0));
  }
  function perspective(fov, aspect, near, far) {
    const f = 1 / Math.tan(fov / 2), r = 1 / (near - far);
    return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * r, -1, 0, 0, 2 * far * near * r, 0];
  }
  function lookAt(eye, at, up) {
    const norm = (v) => { const l = Math.hypot(...v) || 1; return v.map((x) => x / l); };
    const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    const z = norm(eye.map((e, k) => e - at[k])), x = norm(cross(up, z)), y = cross(z, x);
    return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0, -dot(x, eye), -dot(y, eye), -dot(z, eye), 1];
  }
  function multiply(a, b) {
    const out = new Array(16).fill(0);
    for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) for (let k = 0; k < 4; k++) out[j * 4 + i] += a[k * 4 + i] * b[j * 4 + k];
    return out;
  }

  // ---- the motor plots (uPlot) -------------------------------------------------------------------------------
  const charts = [];
  function plots() {
    const time = array("series-time");
    if (!time || !time.length) { $("plots-note").textContent = "No planned moves."; return; }
    $("plots-note").textContent = "Each point: the peak over " + (S.series_points < S.segments.planned ? "the moves it covers" : "one move") +
      " (merged two by two as the print grows, peaks kept). Dashed: the configured limit.";
    const sync = uPlot.sync("motors");
    const make = (title, series, data) => {
      const div = document.createElement("div");
      div.className = "chart";
      $("charts").appendChild(div);
      charts.push(new uPlot({ title, width: 900, height: 150, cursor: { sync: { key: sync.key } }, scales: { x: { time: false } },
        series: [{ label: "s" }].concat(series), axes: [{}, { size: 60 }] }, [Array.from(time)].concat(data), div));
    };
    const nozzle = array("series-nozzle");
    make("nozzle speed (mm/s)", [{ label: "peak", stroke: "#37474f" }], [Array.from(nozzle)]);
    S.motors.forEach((m, i) => {
      const pos = array("series" + i + "-position");
      make(m.name + " position (" + m.unit + ")", [{ label: "position", stroke: "#1565c0" }], [Array.from(pos)]);
      for (const kind of ["speed", "accel"]) {
        const values = Array.from(array("series" + i + "-" + kind)), limit = limitOf(i, kind);
        const series = [{ label: kind === "speed" ? "peak speed" : "peak acceleration", stroke: kind === "speed" ? "#2e7d32" : "#8e24aa" }];
        const data = [values];
        if (limit) { series.push({ label: "limit", stroke: "#d50000", dash: [6, 4] }); data.push(values.map(() => limit)); }
        make(m.name + " " + (kind === "speed" ? "speed (" + m.unit + "/s)" : "acceleration (" + m.unit + "/s²)"), series, data);
      }
    });
  }
  function plotRange(lo, hi) { for (const c of charts) c.setScale("x", { min: lo, max: hi }); }
  $("plots-layer").addEventListener("click", () => {
    const l = S.layers[state.layer];
    if (!l || !l.count) return;
    plotRange(D.start[l.first], D.start[l.first + l.count - 1] + D.duration[l.first + l.count - 1]);
  });
  $("plots-all").addEventListener("click", () => plotRange(0, E.total));

  // ---- controls ----------------------------------------------------------------------------------------------
  function redraw() {
    if (state.view === "3d" && !gl3.tried) { gl3.tried = true; initGl(); colour3d(); }
    const l = S.layers[state.layer];
    $("layer-name").textContent = l ? l.name + (l.z !== null ? " (Z " + fmt(l.z) + ")" : "") : "";
    const part = l && E.layers.find((p) => p.line === l.line);
    $("layer-info").textContent = l ? "Layer " + l.name + ": " + l.count + " segments drawn of " + l.planned + " planned" +
      (part ? ", " + hms(part.time) + (part.lost ? " (the motor limits add " + hms(part.lost) + ")" : "") : "") +
      (l.whole ? "" : ". The page is over its size: this layer shows only its limit hits, slowed moves and refusals (runs of one kind as chords) " +
        "(" + (S.stride === 2 ? "every other layer" : "every " + S.stride + "th layer") + " is whole).") : "";
    legend(state.mode);
    const m = S.map.layers && S.map.layers.find((x) => x.id === state.map);
    const img = state.map !== "none" && state.map !== "reach" ? mapCanvas(state.map) : null;
    $("map-note").textContent = m ? m.title + ": " + (img ? fmt(img.range[0]) + " (blue) … " + fmt(img.range[1]) + " (red). " : "") + m.note
      : state.map === "reach" ? "Where the machine reaches: " + S.map.reach_labels.join(", ") + " (green: reachable)." : "";
    $("layer-canvas").hidden = state.view !== "layer";
    $("gl-canvas").hidden = state.view !== "3d";
    $("gl-note").hidden = state.view !== "3d" || !!gl3.gl;
    if (state.view === "layer") drawLayer(); else draw3d();
    const f = $("focus");
    if (state.focus >= 0) {
      const i = state.focus, r = canvas.getBoundingClientRect();
      const x = (px(D.from[3 * i]) + px(D.to[3 * i])) / 2, y = (py(D.from[3 * i + 1]) + py(D.to[3 * i + 1])) / 2;
      f.dataset.line = String(D.line[i]); f.dataset.cause = String(D.cause[i]);
      f.dataset.x = String(r.left + window.scrollX + x); f.dataset.y = String(r.top + window.scrollY + y);
      f.dataset.rgb = colourOf(state.mode, i).join(",");
    }
  }
  function focusLine(line) {
    const i = segmentOfLine(line);
    if (i === undefined) return;
    state.focus = i; state.layer = layerOf[i]; $("layer").value = String(state.layer);
    state.cx = (D.from[3 * i] + D.to[3 * i]) / 2; state.cy = (D.from[3 * i + 1] + D.to[3 * i + 1]) / 2;
    const len = Math.hypot(D.to[3 * i] - D.from[3 * i], D.to[3 * i + 1] - D.from[3 * i + 1]);
    state.scale = Math.min(400, Math.max(2, 120 / Math.max(len, 0.05)));
    redraw();
  }
  function setup() {
    const colour = $("colour");
    modes.forEach((m) => colour.add(new Option(m.label, m.id)));
    const map = $("map");
    map.add(new Option("nothing", "none"));
    if (S.map.nx) {
      map.add(new Option("reach", "reach"));
      S.map.layers.forEach((l) => map.add(new Option(l.title, l.id)));
    }
    const layer = $("layer");
    layer.max = String(Math.max(0, S.layers.length - 1));
    colour.addEventListener("change", () => { state.mode = modes.find((m) => m.id === colour.value); colour3d(); redraw(); });
    map.addEventListener("change", () => { state.map = map.value; redraw(); });
    layer.addEventListener("input", () => { state.layer = Number(layer.value); redraw(); });
    $("travel").addEventListener("change", (e) => { state.travel = e.target.checked; redraw(); });
    $("view-kind").addEventListener("change", (e) => { state.view = e.target.value; redraw(); });
    const hash = new URLSearchParams(location.hash.slice(1));
    if (hash.get("colour")) { colour.value = hash.get("colour"); state.mode = modes.find((m) => m.id === colour.value) || modes[0]; }
    if (hash.get("map")) { map.value = hash.get("map"); state.map = map.value || "none"; }
    if (hash.get("view")) { $("view-kind").value = hash.get("view"); state.view = $("view-kind").value; }
    state.layer = Math.max(0, S.layers.length - 1);
    if (hash.get("layer")) state.layer = Math.min(S.layers.length - 1, Math.max(0, Number(hash.get("layer"))));
    layer.value = String(state.layer);
    fit();
    if (hash.get("line")) focusLine(Number(hash.get("line"))); else redraw();
  }

  numbers();
  setup();
  plots();
  document.body.dataset.loadMs = String(Math.round(performance.now()));
  $("status").textContent = errors.length ? "errors" : "ready";
  document.body.dataset.ready = errors.length ? "errors" : "yes";
})();
