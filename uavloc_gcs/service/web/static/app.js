// uavloc live map: plain SVG in the search's local frame (east/north metres from the launch
// point, north up). State arrives as server-sent events: "state" (everything) once per
// connection, then "delta" (new track points and events, current vehicles, people and plan).
"use strict";
(() => {
  const NS = "http://www.w3.org/2000/svg";
  const R_EARTH = 6378137.0;
  const svg = document.getElementById("map");
  let S = null;                      // the state as the server sent it, tracks and events merged in
  const view = { cx: 0, cy: 0, s: 1, fitted: false };
  let W = 800, H = 600;

  function el(name, attrs, parent, text) {
    const e = document.createElementNS(NS, name);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    if (parent) parent.appendChild(e);
    return e;
  }
  const px = (e, n) => [(e - view.cx) * view.s + W / 2, (view.cy - n) * view.s + H / 2];
  const metres = (x, y) => [(x - W / 2) / view.s + view.cx, view.cy - (y - H / 2) / view.s];
  const ok = (v) => v !== null && v !== undefined && Number.isFinite(v);
  const fmt = (v, nd) => ok(v) ? v.toFixed(nd) : "-";
  const colors = () => (S && S.static.state_colors) || {};

  // -- view ----------------------------------------------------------------------------------
  function size() {
    const r = svg.getBoundingClientRect();
    W = Math.max(r.width, 100); H = Math.max(r.height, 100);
  }
  function fit() {
    if (!S) return;
    const pts = S.static.area_xy_m.slice();
    pts.push([0, 0]);
    for (const t of Object.values(S.tracks)) for (const p of t) pts.push(p);
    let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
    for (const [x, y] of pts) { x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y); }
    size();
    view.cx = (x0 + x1) / 2; view.cy = (y0 + y1) / 2;
    view.s = Math.min(W / ((x1 - x0) * 1.15 + 20), H / ((y1 - y0) * 1.15 + 20));
    view.fitted = true;
  }
  function zoom(f, x, y) {
    const [e, n] = metres(x ?? W / 2, y ?? H / 2);
    view.s *= f;
    const [e2, n2] = metres(x ?? W / 2, y ?? H / 2);
    view.cx += e - e2; view.cy += n - n2;
    draw();
  }

  // -- drawing -------------------------------------------------------------------------------
  function niceLength(target) {
    const exp = Math.pow(10, Math.floor(Math.log10(target)));
    for (const m of [5, 2, 1]) if (m * exp <= target) return m * exp;
    return exp;
  }
  function toLatLon(e, n) {
    const lat0 = S.static.origin_lat_deg, lon0 = S.static.origin_lon_deg;
    return [lat0 + n / R_EARTH * 180 / Math.PI,
            lon0 + e / (R_EARTH * Math.cos(lat0 * Math.PI / 180)) * 180 / Math.PI];
  }
  function toLocal(lat, lon) {
    const lat0 = S.static.origin_lat_deg, lon0 = S.static.origin_lon_deg;
    return [(lon - lon0) * Math.PI / 180 * R_EARTH * Math.cos(lat0 * Math.PI / 180), (lat - lat0) * Math.PI / 180 * R_EARTH];
  }
  function tiles(g) {
    const tmpl = S.config && S.config.tiles;
    if (!tmpl) return;
    const lat0 = S.static.origin_lat_deg;
    const z = Math.max(0, Math.min(19, Math.round(Math.log2(156543.034 * Math.cos(lat0 * Math.PI / 180) * view.s))));
    const n = 1 << z;
    const tx = (lon) => Math.floor((lon + 180) / 360 * n);
    const ty = (lat) => { const r = lat * Math.PI / 180; return Math.floor((1 - Math.log(Math.tan(r) + 1 / Math.cos(r)) / Math.PI) / 2 * n); };
    const lonOf = (x) => x / n * 360 - 180;
    const latOf = (y) => Math.atan(Math.sinh(Math.PI * (1 - 2 * y / n))) * 180 / Math.PI;
    const [la0, lo0] = toLatLon(...metres(0, H)), [la1, lo1] = toLatLon(...metres(W, 0));
    const xs = [tx(lo0), tx(lo1)], ys = [ty(la1), ty(la0)];
    if ((xs[1] - xs[0] + 1) * (ys[1] - ys[0] + 1) > 120) return;
    for (let x = xs[0]; x <= xs[1]; x++) for (let y = ys[0]; y <= ys[1]; y++) {
      if (x < 0 || y < 0 || x >= n || y >= n) continue;
      const [a, b] = px(...toLocal(latOf(y), lonOf(x))), [c, d] = px(...toLocal(latOf(y + 1), lonOf(x + 1)));
      el("image", { href: tmpl.replace("{z}", z).replace("{x}", x).replace("{y}", y), x: a, y: b,
                    width: c - a + 0.5, height: d - b + 0.5, preserveAspectRatio: "none" }, g);
    }
  }
  function poly(points) { return points.map(([e, n]) => px(e, n).map((v) => v.toFixed(1)).join(",")).join(" "); }

  function placeLabel(boxes, x, y, text, r) {
    // first of 8 spots around (x, y) beyond radius r whose box overlaps no earlier label
    const w = 7.2 * text.length + 4, h = 15, d = Math.max(r, 6) + 3;
    const spots = [[1, -1], [1, 1], [-1, -1], [-1, 1], [1, 0], [-1, 0], [0, -1], [0, 1]];
    let best = null, far = false;
    search:
    for (const k of [1, 2, 3.2]) for (const [sx, sy] of spots) {
      const cx = x + sx * (d * k + (sx ? w / 2 : 0)), cy = y + sy * (d * k + (sy ? h / 2 : 0));
      const b = [cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2];
      if (!boxes.some((o) => b[0] < o[2] && o[0] < b[2] && b[1] < o[3] && o[1] < b[3])) { best = b; far = k > 1; break search; }
    }
    if (!best) { best = [x + d, y - d - h, x + d + w, y - d]; far = false; }
    boxes.push(best);
    return [(best[0] + best[2]) / 2, (best[1] + best[3]) / 2 + 4, far, best];
  }

  function draw() {
    if (!S) return;
    size();
    if (!view.fitted) fit();
    svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    const gTiles = el("g", { class: "tiles" }, svg);
    tiles(gTiles);
    const terrain = S.static.terrain;
    if (terrain && terrain.lines.length) {  // contour lines of the scenario's DEM
      const gTerrain = el("g", { class: "terrain" }, svg);
      for (const c of terrain.lines) {
        el("polyline", { points: poly(c.xy_m), fill: "none", stroke: "#8c6d46", "stroke-width": 0.8,
                         "stroke-opacity": 0.6, class: "contour", "data-level": c.level_m }, gTerrain);
        if (c.xy_m.length >= 2) {  // its height at its middle vertex, so the slope can be read
          const [x, y] = px(...c.xy_m[Math.floor(c.xy_m.length / 2)]);
          const t = el("text", { x: x, y: y - 2, "text-anchor": "middle", "font-size": 10, fill: "#8c6d46",
                                 class: "clabel", "data-level": c.level_m }, gTerrain);
          t.textContent = `${Math.round(c.level_m)} m`;
        }
      }
    }
    const area = S.static.area_xy_m;
    el("polygon", { points: poly(area), fill: "rgba(68,68,68,0.06)", stroke: "#444", "stroke-width": 2, class: "area" }, svg);
    podLayer();
    const vcol = {};
    for (const v of S.vehicles) vcol[v.id] = v.color;
    const gTracks = el("g", { class: "tracks" }, svg);
    for (const [vid, pts] of Object.entries(S.tracks)) {
      if (pts.length > 1) el("polyline", { points: poly(pts), fill: "none", stroke: vcol[vid] || "#333",
                                            "stroke-width": 1.6, "stroke-opacity": 0.8, class: "track", "data-vehicle": vid }, gTracks);
    }
    const gPlan = el("g", { class: "plan" }, svg);
    const located = new Set(S.people.filter((p) => p.state === "located").map((p) => p.id));
    if (S.plan) for (const task of S.plan.tasks) {
      const v = S.vehicles.find((x) => x.id === task.vehicle);
      const looks = task.looks_xy_m.filter((_, i) => !located.has(task.targets[i]));
      if (!looks.length) continue;
      const pts = (v && ok(v.east_m) ? [[v.east_m, v.north_m]] : []).concat(looks);
      el("polyline", { points: poly(pts), fill: "none", stroke: vcol[task.vehicle] || "#333", "stroke-width": 1.4,
                       "stroke-dasharray": "6 4", class: "planned" }, gPlan);
      for (const [e, n] of looks) {
        const [x, y] = px(e, n);
        el("circle", { cx: x, cy: y, r: 4, fill: "#fff", stroke: vcol[task.vehicle] || "#333", "stroke-width": 1.5, class: "look" }, gPlan);
      }
    }
    // launch point
    const [lx, ly] = px(0, 0);
    el("path", { d: `M${lx},${ly - 9} L${lx + 8},${ly + 6} L${lx - 8},${ly + 6} Z`, fill: "#d62728", stroke: "#fff", "stroke-width": 1.2 }, svg);
    const boxes = [];
    const gPeople = el("g", { class: "people" }, svg);
    const gLabels = el("g", { class: "labels" }, svg);
    const C = colors();
    for (const p of S.people) {
      if (!ok(p.east_m)) continue;
      const col = C[p.state] || "#ff7f0e";
      const g = el("g", { class: "person", "data-id": p.id, "data-label": p.label, "data-state": p.state,
                          "data-east": p.east_m, "data-north": p.north_m }, gPeople);
      const [x, y] = px(p.east_m, p.north_m);
      const r = ok(p.radius95_m) ? p.radius95_m * view.s : 0;
      if (p.ambiguous && ok(p.mirror_east_m)) {
        const [mx, my] = px(p.mirror_east_m, p.mirror_north_m);
        el("line", { x1: x, y1: y, x2: mx, y2: my, stroke: col, "stroke-dasharray": "3 3", "stroke-width": 1 }, g);
        const mr = ok(p.mirror_radius95_m) ? p.mirror_radius95_m * view.s : r;
        el("circle", { cx: mx, cy: my, r: Math.max(mr, 2), fill: "none", stroke: col, "stroke-dasharray": "5 3", "stroke-width": 1.2, class: "mirror" }, g);
        el("path", { d: `M${mx - 4},${my - 4} L${mx + 4},${my + 4} M${mx - 4},${my + 4} L${mx + 4},${my - 4}`, stroke: col, "stroke-width": 2 }, g);
        boxes.push([mx - 5, my - 5, mx + 5, my + 5]);
      }
      if (r > 0) el("circle", { cx: x, cy: y, r: r, fill: col, "fill-opacity": 0.14, stroke: col, "stroke-width": 1.2, class: "c95" }, g);
      el("path", { d: `M${x - 5},${y} L${x + 5},${y} M${x},${y - 5} L${x},${y + 5}`, stroke: col, "stroke-width": 3 }, g);
      boxes.push([x - 6, y - 6, x + 6, y + 6]);
    }
    for (const p of S.people) {
      if (!ok(p.east_m)) continue;
      const [x, y] = px(p.east_m, p.north_m);
      const text = (p.label || "#" + p.id) + (p.ambiguous ? " ?" : "");
      const [tx, ty, far, b] = placeLabel(boxes, x, y, text, 6);
      if (far) {  // a leader line to the nearest point of the label's box
        const lx = Math.max(b[0], Math.min(x, b[2])), ly = Math.max(b[1], Math.min(y, b[3]));
        el("line", { x1: x, y1: y, x2: lx, y2: ly, stroke: C[p.state] || "#ff7f0e", "stroke-width": 0.8 }, gLabels);
      }
      el("text", { x: tx, y: ty, "text-anchor": "middle", fill: C[p.state] || "#ff7f0e", "font-weight": 700, class: "plabel" }, gLabels, text);
    }
    const gVeh = el("g", { class: "vehicles" }, svg);
    for (const v of S.vehicles) {
      if (!ok(v.east_m)) continue;
      const [x, y] = px(v.east_m, v.north_m);
      const col = v.lost ? "#888" : v.color;
      const g = el("g", { class: "vehicle", "data-id": v.id, "data-east": v.east_m, "data-north": v.north_m,
                          transform: `translate(${x.toFixed(1)},${y.toFixed(1)})` }, gVeh);
      el("path", { d: "M0,-11 L7,8 L0,4 L-7,8 Z", fill: col, stroke: "#fff", "stroke-width": 1.5,
                   transform: `rotate(${ok(v.heading_deg) ? v.heading_deg : 0})` }, g);
      const text = `UAV${v.id}` + (v.note ? " LOST IN THE AIR (last heard here)" : v.lost ? " LOST" : "");
      el("text", { x: 11, y: -8, fill: col, "font-weight": 700 }, g, text);
    }
    decorations();
  }

  // the achieved POD of every cell (search/coverage.py): red 0 (unsearched) .. green at the target
  function podColor(p, target) {
    const f = Math.max(0, Math.min(1, target > 0 ? p / target : 1));
    const mix = (a, b, t) => Math.round(a + (b - a) * t);
    return f < 0.5 ? `rgb(214,${mix(39, 190, f * 2)},40)` : `rgb(${mix(214, 44, (f - 0.5) * 2)},${mix(190, 160, (f - 0.5) * 2)},${mix(40, 44, (f - 0.5) * 2)})`;
  }
  function podLayer() {
    const cells = S.static.pod_cells, cov = S.coverage;
    if (!cells || !cov || !cov.pod || cov.pod.length !== cells.xy_m.length) return;
    const g = el("g", { class: "pod" }, svg);
    const h = cells.cell_m / 2, w = cells.cell_m * view.s + 0.5;
    cells.xy_m.forEach(([e, n], i) => {
      const [x, y] = px(e - h, n + h);
      el("rect", { x: x.toFixed(1), y: y.toFixed(1), width: w.toFixed(1), height: w.toFixed(1),
                   fill: podColor(cov.pod[i], cov.pod_target), "fill-opacity": 0.33, class: "podcell",
                   "data-pod": cov.pod[i] }, g);
    });
  }

  function decorations() {
    // scale bar (bottom right) and north arrow (top left)
    const L = niceLength(W / 5 / view.s), w = L * view.s;
    const g = el("g", { class: "scalebar" }, svg);
    const x1 = W - 20, x0 = x1 - w, y = H - 22;
    el("rect", { x: x0 - 8, y: y - 20, width: w + 16, height: 30, fill: "rgba(255,255,255,0.85)", stroke: "#bbb" }, g);
    el("path", { d: `M${x0},${y - 5} L${x0},${y} L${x1},${y} L${x1},${y - 5}`, fill: "none", stroke: "#222", "stroke-width": 2 }, g);
    el("text", { x: (x0 + x1) / 2, y: y - 7, "text-anchor": "middle" }, g, L >= 1000 ? `${L / 1000} km` : `${L} m`);
    const n = el("g", { class: "north" }, svg);
    el("path", { d: "M24,12 L31,34 L24,29 L17,34 Z", fill: "#222" }, n);
    el("text", { x: 24, y: 48, "text-anchor": "middle", "font-weight": 700 }, n, "N");
  }

  // -- panels --------------------------------------------------------------------------------
  // UTC as the daemon maps it (service/clock.py): under a simulator's speed-up the vehicles' clock
  // runs ahead of UTC, so times come from the server, already mapped, with the clock they are in
  function utc(iso) {
    return iso ? iso.slice(11, 19) : "";
  }
  function row(tbody, cells, attrs) {
    const tr = document.createElement("tr");
    for (const [k, v] of Object.entries(attrs || {})) tr.setAttribute(k, v);
    for (const c of cells) {
      const td = document.createElement("td");
      if (c instanceof Node) td.appendChild(c); else td.textContent = c;
      tr.appendChild(td);
    }
    tbody.appendChild(tr);
    return tr;
  }
  // The operator's word that a waiting vehicle has a fresh pack (issue 38): two clicks within 5 s
  // (the first asks), then a POST the server records as `uavloc pack-fresh` does; the daemon still
  // refuses a pack the vehicle itself reports as not fresh. The server's sentence is shown under it.
  const asking = {}, said = {};
  function freshButton(vid) {
    const b = document.createElement("button");
    b.className = "fresh"; b.setAttribute("data-vehicle", vid);
    const sure = asking[vid] && asking[vid] > Date.now();
    b.textContent = sure ? "sure? click again" : "fresh pack fitted";
    b.onclick = async () => {
      if (!(asking[vid] && asking[vid] > Date.now())) { asking[vid] = Date.now() + 5000; panels(); return; }
      delete asking[vid];
      try {
        const r = await fetch(`api/vehicles/${vid}/pack-fresh`, { method: "POST", headers: { "X-Uavloc-Command": "pack-fresh" } });
        said[vid] = (await r.json()).text;
      } catch (e) { said[vid] = `not sent: ${e}`; }
      panels();
    };
    return b;
  }
  function panels() {
    document.getElementById("title").textContent = `uavloc · ${S.static.name}`;
    const clock = utc(S.clock_utc);
    document.getElementById("clock").textContent = `mission t = ${fmt(S.t_s, 1)} s` +
      (clock ? ` (${clock} ${S.clock_label === "UTC" ? "UTC" : "UTC, this computer's clock"})` : "");
    document.getElementById("clock").title = S.clock_label || "";
    const nLoc = S.people.filter((p) => p.state === "located").length;
    document.getElementById("summary").textContent =
      `located ${nLoc}/${S.people.length} within ${S.static.required_accuracy_m} m` +
      (ok(S.slots) ? ` · slots ${S.slots}` : "") + (ok(S.replans) ? ` · replans ${S.replans}` : "") +
      (S.coverage ? ` · POD ${fmt(S.coverage.pod_overall, 2)} (target ${fmt(S.coverage.pod_target, 2)})` +
                    (S.coverage.unsearched_m2 > 0 ? ` · unsearched ${fmt(S.coverage.unsearched_m2 / 1e6, 3)} km²` : "") : "") +
      (S.located_by ? ` · ${S.located_by}` : "");
    document.getElementById("summary").title = S.coverage ? S.coverage.statement : "";
    const alert = document.getElementById("alert");  // a vehicle lost in the air, said first
    alert.textContent = S.alert || "";
    alert.hidden = !S.alert;
    const vb = document.querySelector("#vehicles tbody");
    vb.textContent = "";
    for (const v of S.vehicles) {
      const sw = document.createElement("span");
      sw.textContent = `UAV${v.id}`; sw.style.color = v.color; sw.className = "state";
      const doing = document.createElement("span");
      doing.textContent = (v.note ? "LOST IN THE AIR " : v.lost ? "LOST " : "") + (v.phase || "") + (ok(v.mission_seq) && ok(v.mission_total) ? ` (${v.mission_seq}/${v.mission_total})` : "");
      if (v.phase === "waiting for pack" && !S.finished) doing.appendChild(freshButton(v.id));
      if (said[v.id]) { const m = document.createElement("div"); m.className = "said"; m.textContent = said[v.id]; doing.appendChild(m); }
      row(vb, [sw, v.mode || "?", ok(v.battery_pct) ? `${v.battery_pct}%` : "-", doing], { "data-vehicle": v.id });
    }
    const pb = document.querySelector("#people tbody");
    pb.textContent = "";
    const C = colors();
    for (const p of S.people) {
      const st = document.createElement("span");
      st.textContent = p.state + (p.ambiguous ? " (2 candidates)" : ""); st.className = "state"; st.style.color = C[p.state] || "#333";
      const nm = document.createElement("span");
      const b = document.createElement("b"); b.textContent = p.label || "";
      const id = document.createElement("span"); id.className = "eid"; id.textContent = ` #${p.id}`;
      nm.appendChild(b); nm.appendChild(id);
      if (p.state === "located" && ok(p.lat_deg) && ok(p.lon_deg)) {  // where a rescuer goes
        const ll = document.createElement("div"); ll.className = "latlon";
        ll.textContent = `${p.lat_deg.toFixed(6)}, ${p.lon_deg.toFixed(6)}`;
        nm.appendChild(ll);
      }
      row(pb, [nm, st, ok(p.radius95_m) ? `${fmt(p.radius95_m, 1)} m` : "-", utc(p.time_utc) || "-"], { "data-id": p.id });
      if (p.reason && p.state !== "located") {
        const tr = row(pb, [""]); tr.firstChild.colSpan = 4; tr.firstChild.className = "reason"; tr.firstChild.textContent = p.reason;
      }
    }
    const lg = document.getElementById("legend");
    lg.textContent = "";
    for (const [k, c] of Object.entries(C)) {
      if (k === "never heard") continue;
      const sw = document.createElement("span"); sw.className = "sw"; sw.style.background = c;
      lg.appendChild(sw); lg.appendChild(document.createTextNode(k));
    }
    lg.appendChild(document.createTextNode(" · dashed: planned looks, mirror candidate"));
    if (S.coverage) lg.appendChild(document.createTextNode(" · cells: achieved POD, red 0 (unsearched) to green (target)"));
  }
  function addEvents(list) {
    const ol = document.getElementById("events");
    for (const ev of list) {
      // a run of the same event with other numbers ("Reached command #5", "#6", ...) is one line
      // that keeps the latest text and counts, not a flood
      const key = `${ev.kind}|${ev.vehicle}|${String(ev.text).replace(/[0-9.]+/g, "#")}`;
      const top = ol.firstChild;
      const li = top && top.dataset.key === key ? top : document.createElement("li");
      const n = li === top ? Number(li.dataset.n || 1) + 1 : 1;
      li.textContent = ""; li.dataset.key = key; li.dataset.n = n;
      const t = document.createElement("span"); t.className = "t"; t.textContent = ok(ev.t_s) ? `${ev.t_s.toFixed(1)} s` : "";
      const k = document.createElement("span"); k.className = "k"; k.textContent = ev.kind;
      li.appendChild(t); li.appendChild(k); li.appendChild(document.createTextNode(ev.text + (n > 1 ? ` (${n}x)` : "")));
      if (li !== top) ol.insertBefore(li, ol.firstChild);
    }
    while (ol.children.length > 300) ol.removeChild(ol.lastChild);
  }

  // -- live updates ----------------------------------------------------------------------------
  function link(text, cls) { const e = document.getElementById("link"); e.textContent = text; e.className = "link " + cls; }
  function connect() {
    const es = new EventSource("api/stream");
    es.addEventListener("state", (m) => {
      S = JSON.parse(m.data);
      document.getElementById("events").textContent = "";
      addEvents(S.events);
      link(S.finished ? "search finished" : "live", S.finished ? "done" : "up");
      panels(); draw();
    });
    es.addEventListener("delta", (m) => {
      if (!S) return;
      const d = JSON.parse(m.data);
      for (const [v, pts] of Object.entries(d.tracks_append)) (S.tracks[v] = S.tracks[v] || []).push(...pts);
      S.events.push(...d.events_append);
      addEvents(d.events_append);
      for (const k of ["t_s", "epoch_unix_s", "slots", "replans", "finished", "vehicles", "people", "plan", "coverage"]) S[k] = d[k];
      if (S.finished) {  // the search's clock stops at its end (--web-keep serves on afterwards)
        if (S.t_end == null) S.t_end = S.t_s;
        S.t_s = S.t_end;
      }
      link(S.finished ? "search finished" : "live", S.finished ? "done" : "up");
      panels(); draw();
    });
    es.onerror = () => link(S && S.finished ? "search finished (server stopped)" : "disconnected, retrying...", S && S.finished ? "done" : "down");
  }

  // -- interaction -----------------------------------------------------------------------------
  let drag = null;
  svg.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY]; svg.style.cursor = "grabbing"; });
  window.addEventListener("mouseup", () => { drag = null; svg.style.cursor = "grab"; });
  window.addEventListener("mousemove", (e) => {
    if (!drag) return;
    view.cx -= (e.clientX - drag[0]) / view.s; view.cy += (e.clientY - drag[1]) / view.s;
    drag = [e.clientX, e.clientY]; draw();
  });
  svg.addEventListener("wheel", (e) => {
    e.preventDefault();
    const r = svg.getBoundingClientRect();
    zoom(e.deltaY < 0 ? 1.25 : 0.8, e.clientX - r.left, e.clientY - r.top);
  }, { passive: false });
  document.getElementById("fit").onclick = () => { fit(); draw(); };
  document.getElementById("zoomin").onclick = () => zoom(1.5);
  document.getElementById("zoomout").onclick = () => zoom(1 / 1.5);
  window.addEventListener("resize", () => draw());
  connect();
})();
