// ringsync scope: reads the /ws stream (docs/scope.md), holds what it received, plots it.
"use strict";
(function () {
  const MAGIC = 0x50435352, HEADER = 32, NODE_FIELDS = 5;
  const CAP = 120000;                       // rows held (2 min of a 1 ms ring)
  // matplotlib's tab10 first, as the reports and the Python package colour the axes.
  const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd"];
  const STATE_COLORS = ["#2a2", "#e90", "#f60", "#999", "#d22", "#800"];
  const HIST_EDGES = [0, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, Infinity];
  const body = document.body;
  let hello = null, data = [], nodes = [], events = [], plots = {}, paused = false, follow = true;
  // The ring's broken link as the master last reported it (link j joins node j-1 to node j).
  let brokenLink = null;
  let lastSeq = -1, nextFirst = -1, lastDrops = 0, hist = new Array(HIST_EDGES.length - 1).fill(0);
  let histMax = 0, lastDraw = 0, drawTimer = null, ws = null;
  const counter = (k, v) => { body.dataset[k] = String(v); };
  const bump = (k, d) => counter(k, Number(body.dataset[k]) + (d === undefined ? 1 : d));
  const col = (axis, j) => 2 + 6 * axis + j;   // axis 0-based; j: e, eps, xd, u, clk, status
  const $ = (id) => document.getElementById(id);

  function plot(id, title, series, extra) {
    const el = $(id);
    const opts = {
      width: Math.max(500, el.clientWidth || 700), height: 170,
      scales: { x: { time: false } },
      axes: [{ label: "t [s]" }, { size: 72, space: 24, values: (u, vals) => vals.map((v) => (Math.abs(v) >= 1e4 || (v !== 0 && Math.abs(v) < 1e-3) ? v.toExponential(1) : String(+v.toPrecision(4)))) }],
      cursor: { drag: { x: true, y: false } },
      legend: { live: true },
      series: [{ label: "t [s]" }].concat(series),
      hooks: { setSelect: [() => { follow = false; }] },
    };
    if (extra) extra(opts);
    const u = new uPlot(opts, [[]].concat(series.map(() => [])), el);
    return u;
  }

  function setup() {
    const n = hello.shown_axes;
    data = hello.columns.map(() => []);
    const axisSeries = (unit) => Array.from({ length: n }, (_, i) => ({
      label: "axis " + (i + 1), stroke: COLORS[i % COLORS.length], width: 1,
      value: (u, v) => v == null ? "—" : v.toPrecision(4) + " " + unit,
    }));
    for (const k of Object.keys(plots)) { plots[k].u.destroy(); }
    plots = {};
    const mk = (name, j, unit) => { plots[name] = { u: plot("p-" + name, name, axisSeries(unit)), cols: Array.from({ length: n }, (_, i) => col(i, j)) }; };
    mk("e", 0, "rad"); mk("xd", 2, "rad"); mk("u", 3, "V"); mk("clk", 4, "ns");
    // ε with its trip limits (dashed, ± the largest set).
    const trip = Math.max(0, ...hello.monitor.sync.trip_rad);
    const s = axisSeries("rad");
    if (trip > 0) {
      s.push({ label: "+trip", stroke: "#d22", dash: [5, 5], width: 1 });
      s.push({ label: "−trip", stroke: "#d22", dash: [5, 5], width: 1 });
    }
    plots.eps = { u: plot("p-eps", "eps", s), cols: Array.from({ length: n }, (_, i) => col(i, 1)), trip: trip };
    const rt = hello.source === "rt";
    $("s-late").style.display = rt ? "" : "none";
    plots.late = { u: plot("p-late", "late", [{ label: "lateness", stroke: "#555", width: 1, value: (u, v) => v == null ? "—" : v.toFixed(1) + " µs" }]), cols: [1] };
    $("what").textContent = hello.scenario + " · " + hello.axes + " axes · " + (hello.cycle_s * 1e3) + " ms cycle · " +
      hello.controller + " · " + (rt ? "real time" : "simulator replay at " + hello.speed + "×");
    const m = hello.monitor, fmt = (l) => l.warn_rad.join("/") + " warn, " + l.trip_rad.join("/") + " trip [rad], filter " + (l.filter_s * 1e3).toFixed(1) + " ms, " + l.reaction;
    $("limits").textContent = "sync ε: " + fmt(m.sync) + " · following e: " + fmt(m.following) + " · hard limit |e| ≤ " + hello.following_error_limit_rad + " rad";
    $("hist-note").textContent = rt ? "" : "The simulator has no loop lateness.";
    const mach = hello.machine;
    $("s-xy").style.display = mach && mach.axes.length >= 2 ? "" : "none";
    if (mach && mach.axes.length >= 2) {
      $("xy-title").textContent = "Path in " + mach.axes[0].name + mach.axes[1].name + " [mm]: commanded (grey), actual (red)";
    }
    drawRing(); drawTables(); drawHist(); drawXY(0);
  }

  // A machine axis's commanded and actual positions [mm] from its drives' x^d and e [rad]
  // (a gantry pair: their mean), rows from `from` on.
  function machineAxis(a, from) {
    const rows = data[0].length - from, cmd = new Array(rows).fill(0), act = new Array(rows).fill(0);
    for (const [i, k] of a.drives) {
      const xd = data[col(i, 2)], e = data[col(i, 0)];
      for (let r = 0; r < rows; r++) {
        cmd[r] += xd[from + r] / k / a.drives.length;
        act[r] += (xd[from + r] - e[from + r]) / k / a.drives.length;
      }
    }
    return [cmd, act];
  }

  // The XY panel: the path over the window shown, equal scales on both axes.
  function drawXY(from) {
    const mach = hello && hello.machine;
    if (!mach || mach.axes.length < 2) return;
    const c = $("xy"), g = c.getContext("2d"), W = c.width, H = c.height, pad = 34;
    g.clearRect(0, 0, W, H);
    if (!data[0] || data[0].length <= from) return;
    const [xc, xa] = machineAxis(mach.axes[0], from), [yc, ya] = machineAxis(mach.axes[1], from);
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const [xs, ys] of [[xc, yc], [xa, ya]]) {
      for (let r = 0; r < xs.length; r++) {
        if (Number.isFinite(xs[r]) && Number.isFinite(ys[r])) {
          x0 = Math.min(x0, xs[r]); x1 = Math.max(x1, xs[r]); y0 = Math.min(y0, ys[r]); y1 = Math.max(y1, ys[r]);
        }
      }
    }
    if (!Number.isFinite(x0)) return;
    const span = Math.max(x1 - x0, y1 - y0, 1e-3) * 1.08, mx = (x0 + x1) / 2, my = (y0 + y1) / 2;
    const px = (x) => pad + (x - (mx - span / 2)) / span * (W - 2 * pad);
    const py = (y) => H - pad - (y - (my - span / 2)) / span * (H - 2 * pad);
    g.strokeStyle = "#ddd"; g.strokeRect(pad, pad, W - 2 * pad, H - 2 * pad);
    g.fillStyle = "#555"; g.font = "10px sans-serif";
    g.fillText((mx - span / 2).toPrecision(4), pad, H - pad + 14);
    g.fillText((mx + span / 2).toPrecision(4), W - pad - 40, H - pad + 14);
    g.fillText((my + span / 2).toPrecision(4), 2, pad + 4);
    g.fillText((my - span / 2).toPrecision(4), 2, H - pad);
    const line = (xs, ys, colour, width) => {
      g.strokeStyle = colour; g.lineWidth = width; g.beginPath();
      let started = false;
      for (let r = 0; r < xs.length; r++) {
        if (!Number.isFinite(xs[r]) || !Number.isFinite(ys[r])) { started = false; continue; }
        if (started) g.lineTo(px(xs[r]), py(ys[r])); else { g.moveTo(px(xs[r]), py(ys[r])); started = true; }
      }
      g.stroke();
    };
    line(xc, yc, "#999", 3); line(xa, ya, "#d62728", 1);
    const last = xc.length - 1, dev = Math.hypot(xa[last] - xc[last], ya[last] - yc[last]);
    c.dataset.points = String(xc.length);
    $("xy-note").textContent = mach.program + ": commanded " + xc[last].toFixed(3) + ", " + yc[last].toFixed(3) +
      " mm; actual minus commanded " + (dev * 1e3).toFixed(2) + " µm (along and across the path; summary.json has the contour error).";
  }

  function onFrame(buf) {
    const dv = new DataView(buf);
    if (buf.byteLength < HEADER || dv.getUint32(0, true) !== MAGIC || !hello) return;
    const seq = dv.getUint32(4, true), drops = dv.getUint32(8, true), skipped = dv.getUint32(12, true);
    const first = dv.getUint32(16, true), cycles = dv.getUint32(20, true);
    const rows = dv.getUint16(24, true), stride = dv.getUint16(26, true);
    const cols = dv.getUint16(28, true), nn = dv.getUint16(30, true);
    if (buf.byteLength !== HEADER + 4 * (rows * cols + nn * NODE_FIELDS)) return;
    // Continuity: the next update starts where this one ended unless samples were dropped
    // (drops) or this client skipped updates (skipped).
    if (nextFirst >= 0 && first !== nextFirst && drops === lastDrops) bump("gaps");
    nextFirst = first + cycles; lastSeq = seq; lastDrops = drops;
    const f = new Float32Array(buf, HEADER, rows * cols);
    for (let c = 0; c < cols && c < data.length; c++) {
      const d = data[c];
      for (let r = 0; r < rows; r++) d.push(f[c * rows + r]);
    }
    for (let r = 0; r < rows; r++) {
      const late = f[1 * rows + r];
      if (!Number.isNaN(late)) {
        let b = 0; while (b < hist.length - 1 && late >= HIST_EDGES[b + 1]) b++;
        hist[b]++; histMax = Math.max(histMax, late);
      }
    }
    if (data[0].length > CAP * 1.1) { const cut = data[0].length - CAP; for (const d of data) d.splice(0, cut); }
    const u = new Uint32Array(buf.slice(HEADER + 4 * rows * cols));
    nodes = Array.from({ length: nn }, (_, i) => Array.from(u.slice(i * NODE_FIELDS, (i + 1) * NODE_FIELDS)));
    bump("frames"); counter("rows", data[0].length); counter("seq", seq); counter("drops", drops); counter("skipped", skipped);
    $("counts").textContent = "updates " + body.dataset.frames + " · seq " + seq + " · rows " + data[0].length +
      " · dropped " + drops + " · skipped " + skipped + (stride > 1 ? " · every " + stride + ". cycle" : "");
    schedule();
  }

  function schedule() {
    if (paused || drawTimer !== null) return;
    const wait = Math.max(0, 16 - (performance.now() - lastDraw));
    drawTimer = setTimeout(() => { drawTimer = null; draw(); }, wait);
  }

  function draw() {
    lastDraw = performance.now();
    const t = data[0] || [];
    if (!t.length) return;
    const w = Number($("window").value);
    const tmax = t[t.length - 1];
    let from = 0;
    if (w > 0 && follow) { while (from < t.length && t[from] < tmax - w) from++; }
    const view = (c) => (from > 0 ? data[c].slice(from) : data[c]);
    const tv = view(0);
    for (const k of Object.keys(plots)) {
      const p = plots[k];
      const d = [tv].concat(p.cols.map((c) => view(c).map((v) => (Number.isNaN(v) ? null : v))));
      if (p.trip) { d.push(tv.map(() => p.trip)); d.push(tv.map(() => -p.trip)); }
      if (follow) p.u.setData(d); else p.u.setData(d, false);
    }
    drawRing(); drawTables(); drawHist(); drawXY(from);
    bump("draws"); counter("drawn", t.length);
  }

  function statusOf(axis) { const s = data[col(axis, 5)]; return s && s.length ? s[s.length - 1] : 1; }
  function last(c) { const d = data[c]; return d && d.length ? d[d.length - 1] : NaN; }

  function drawRing() {
    if (!hello) return;
    const svg = $("ring"), n = Math.min(hello.axes, hello.shown_axes), cx = 205, cy = 128, r = 86;
    const names = ["master"].concat(Array.from({ length: n }, (_, i) => "slave " + (i + 1)));
    const pos = names.map((_, i) => { const a = -Math.PI / 2 + 2 * Math.PI * i / names.length; return [cx + r * Math.cos(a), cy + r * Math.sin(a)]; });
    let s = '<defs><marker id="arr" markerWidth="8" markerHeight="8" refX="7" refY="3" orient="auto"><path d="M0,0 L0,6 L7,3 z" fill="#888"/></marker></defs>';
    for (let i = 0; i < names.length; i++) {
      const [x1, y1] = pos[i], [x2, y2] = pos[(i + 1) % names.length];
      const dx = x2 - x1, dy = y2 - y1, L = Math.hypot(dx, dy), k = 22 / L;
      // Line i is link i + 1; marked only when every node is shown.
      const broken = brokenLink === i + 1 && n === hello.axes;
      s += `<line x1="${x1 + dx * k}" y1="${y1 + dy * k}" x2="${x2 - dx * k}" y2="${y2 - dy * k}" stroke="${broken ? "#d22" : "#888"}" stroke-width="2"${broken ? ' stroke-dasharray="4 4" data-broken="1"' : ""} marker-end="url(#arr)"/>`;
    }
    names.forEach((nm, i) => {
      const st = nodes[i] ? nodes[i][4] : 0, [x, y] = pos[i];
      const c = nodes[i] ? STATE_COLORS[st] || "#000" : "#ccc";
      s += `<circle cx="${x}" cy="${y}" r="20" fill="${c}" stroke="#333" data-node="${i}" data-state="${st}"><title>${nm}: ${hello.node_states[st] || st}</title></circle>`;
      s += `<text x="${x}" y="${y + 4}" text-anchor="middle" font-size="10" fill="#fff">${i === 0 ? "M" : i}</text>`;
      const lx = x + (x - cx) * 0.5, ly = y + (y - cy) * 0.38 + (Math.abs(x - cx) < 5 ? (y < cy ? -2 : 12) : 4);
      s += `<text x="${lx}" y="${ly}" text-anchor="middle" font-size="10">${hello.node_states[st] || ""}</text>`;
    });
    svg.innerHTML = s;
  }

  function drawTables() {
    if (!hello) return;
    const n = hello.shown_axes, b = hello.status_bits;
    const dot = (on, cls) => `<span class="dot ${on ? cls : "off"}"></span>`;
    let h = "<tr><th>axis</th><th>in sync</th><th>ε warn</th><th>ε trip</th><th>e warn</th><th>e trip</th><th>ε [rad]</th><th>e [rad]</th><th>drive</th></tr>";
    for (let i = 0; i < n; i++) {
      const s = statusOf(i);
      const drive = s & b.torque_off ? "torque off" : s & b.braking ? "braking" : s & b.stopping ? "stopping" : "running";
      h += `<tr data-axis="${i + 1}" data-status="${s}"><td>${i + 1}</td><td>${dot(s & b.in_sync, "on")}</td><td>${dot(s & b.sync_warning, "warn")}</td><td>${dot(s & b.sync_trip, "trip")}</td>` +
        `<td>${dot(s & b.following_warning, "warn")}</td><td>${dot(s & b.following_trip, "trip")}</td>` +
        `<td>${last(col(i, 1)).toFixed(5)}</td><td>${last(col(i, 0)).toFixed(4)}</td><td>${drive}</td></tr>`;
    }
    $("mon").innerHTML = h;
    let t = "<tr><th>node</th><th>state</th><th>frames</th><th>rejected</th><th>retries</th><th>outages</th></tr>";
    nodes.forEach((v, i) => {
      t += `<tr><td>${i === 0 ? "master" : "slave " + i}</td><td>${hello.node_states[v[4]] || v[4]}</td><td>${v[0]}</td><td>${v[1]}</td><td>${v[2]}</td><td>${v[3]}</td></tr>`;
    });
    $("nodes").innerHTML = t;
  }

  function drawHist() {
    const c = $("hist"), g = c.getContext("2d"), W = c.width, H = c.height, total = hist.reduce((a, b) => a + b, 0);
    g.clearRect(0, 0, W, H);
    const bw = (W - 20) / hist.length, top = Math.max(1, ...hist);
    g.font = "9px sans-serif"; g.fillStyle = "#333";
    hist.forEach((v, i) => {
      // Log scale: one cycle in a bin is visible beside thousands.
      const h = v > 0 ? (H - 30) * Math.log10(1 + v) / Math.log10(1 + top) : 0;
      g.fillStyle = i >= 7 ? "#d62728" : "#1f77b4";
      g.fillRect(10 + i * bw + 1, H - 18 - h, bw - 2, h);
      g.fillStyle = "#333";
      g.fillText(HIST_EDGES[i] + (i === hist.length - 1 ? "+" : ""), 10 + i * bw + 1, H - 6);
      if (v) g.fillText(String(v), 10 + i * bw + 1, H - 20 - h);
    });
    if (total) $("hist-note").textContent = total + " cycle starts; largest " + histMax.toFixed(1) + " µs; bins [µs], log scale.";
  }

  function onText(t) {
    let m; try { m = JSON.parse(t); } catch (e) { return; }
    if (m.type === "hello") { hello = m; setup(); }
    else if (m.type === "event") {
      events.push(m); bump("events");
      const div = document.createElement("div");
      const trip = (m.kind === "monitor" && m.level === "trip") || m.step === "group_stop";
      div.className = trip ? "trip" : (m.kind === "monitor" && m.change === "raised") || m.kind === "ring" ? "warn" : "";
      if (m.kind === "ring") {
        brokenLink = m.broken_link;
        div.textContent = m.time_s.toFixed(4) + " s  ring: " + m.from + " → " + m.to + " (cycle " + m.cycle + ")";
        drawRing();
      } else {
        div.textContent = m.time_s.toFixed(4) + " s  axis " + m.axis + "  " + (m.kind === "monitor"
          ? m.monitor + " " + m.level + " " + m.change + " (" + m.value_rad.toFixed(5) + " rad)"
          : m.step + ": " + m.detail);
      }
      $("events").prepend(div);
    } else if (m.type === "end") {
      events.push(m); counter("ended", 1);
      const div = document.createElement("div");
      div.textContent = "run ended: " + (m.group_stop ? "group stop at " + m.group_stop.time_s.toFixed(3) + " s (" + m.group_stop.reason + ", axis " + m.group_stop.axis + ")" : "no group stop") +
        (m.track_rmse !== undefined ? "; Track-RMSE " + m.track_rmse.toFixed(6) + " rad, Sync-RMSE " + m.sync_rmse.toFixed(7) + " rad" : "");
      $("events").prepend(div);
      $("conn").className = "end"; schedule();
    }
  }

  function connect() {
    ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
    ws.binaryType = "arraybuffer";
    ws.onopen = () => { $("conn").className = "ok"; };
    ws.onclose = () => { if (body.dataset.ended !== "1") $("conn").className = "bad"; };
    ws.onmessage = (ev) => { if (typeof ev.data === "string") onText(ev.data); else onFrame(ev.data); };
  }

  function save(name, type, text) {
    const a = document.createElement("a");
    a.href = URL.createObjectURL(new Blob([text], { type: type }));
    a.download = name; document.body.appendChild(a); a.click(); a.remove();
  }

  $("pause").onclick = () => { paused = !paused; $("pause").textContent = paused ? "Resume" : "Pause"; if (!paused) schedule(); };
  $("unzoom").onclick = () => { follow = true; if (paused) { paused = false; $("pause").textContent = "Pause"; } schedule(); };
  $("window").onchange = () => { follow = true; schedule(); };
  $("csv").onclick = () => {
    if (!hello) return;
    const rows = [hello.columns.join(",")];
    for (let r = 0; r < data[0].length; r++) rows.push(data.map((d) => (Number.isNaN(d[r]) ? "" : d[r])).join(","));
    save("ringsync-scope.csv", "text/csv", rows.join("\n") + "\n");
  };
  $("json").onclick = () => {
    if (!hello) return;
    const columns = {};
    hello.columns.forEach((c, i) => { columns[c] = data[i].map((v) => (Number.isNaN(v) ? null : v)); });
    save("ringsync-scope.json", "application/json", JSON.stringify({ hello: hello, columns: columns, nodes: nodes, events: events }));
  };
  window.ringsyncScope = { data: () => data, hello: () => hello, nodes: () => nodes, events: () => events };
  connect();
})();
