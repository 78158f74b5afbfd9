// softnc web panel: plain JavaScript, no build step. Talks to softnc-web over one
// WebSocket (live status in, commands out) and a few fetches (programs, uploads).
"use strict";

const $ = (id) => document.getElementById(id);
// a status older than this is not shown as live (the panel sends >= 20 per second)
const STALE_MS = 400;
// a held continuous jog is renewed this often (the panel stops it after 150 ms quiet)
const JOG_RENEW_MS = 50;

const S = {
  ws: null, open: false, authorized: false, lastStatusAt: 0, link: "lost",
  status: null, nextId: 1, programs: [], selected: null, listingFor: null,
  plan: null, planFor: null, trail: [], trailJob: null, trailFrom: "live", jobs: [],
  jobSelected: null, trace: null, traceFetchedFor: null,
  jogTimer: null, jogAxis: null, token: sessionStorage.getItem("softnc-token") || "",
};

// ---------- connection ----------
function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  S.ws = ws;
  ws.onopen = () => {
    S.open = true;
    if (S.token) ws.send(JSON.stringify({ t: "auth", token: S.token }));
  };
  ws.onmessage = (e) => onMessage(JSON.parse(e.data));
  ws.onclose = () => {
    S.open = false; S.authorized = false; markStale(); stopJog();
    setTimeout(connect, 1000);
  };
  ws.onerror = () => ws.close();
}

function send(msg) {
  if (S.ws && S.open) { S.ws.send(JSON.stringify(msg)); return true; }
  log("not connected: " + (msg.request ? Object.values(msg.request)[0] : msg.t) + " not sent", true);
  return false;
}

function cmd(request) {
  if (!S.authorized) { log("read-only: log in with the operator token", true); }
  const id = S.nextId++;
  send({ t: "cmd", id, request });
  return id;
}

function onMessage(m) {
  switch (m.t) {
    case "hello":
      break;
    case "auth":
      S.authorized = m.ok;
      $("auth-state").textContent = m.ok ? "operator" : "read-only";
      if (!m.ok) { log(m.message, true); sessionStorage.removeItem("softnc-token"); S.token = ""; }
      if (m.ok) loadPrograms();
      break;
    case "status":
      S.link = m.link;
      if (m.link === "ok") { S.lastStatusAt = performance.now(); S.status = m.status; render(m.status); }
      else { S.lastStatusAt = 0; $("link").title = m.error || ""; }
      updateLive();
      break;
    case "jobs":
      S.jobs = m.jobs || []; renderJobs();
      break;
    case "reply":
      if (m.reply && m.reply.reply === "offsets") renderOffsets(m.reply.body);
      else if (m.reply && m.reply.reply === "tools") renderTools(m.reply.body);
      else log(m.message, !m.ok);
      // a work offset set: the table read again
      if (m.id && m.id === S.offsetSetId) { S.offsetSetId = null; cmd({ command: "offsets" }); }
      break;
  }
}

function live() {
  return S.open && S.link === "ok" && performance.now() - S.lastStatusAt < STALE_MS;
}

function updateLive() {
  const ok = live();
  document.body.classList.toggle("stale", !ok);
  const l = $("link");
  l.textContent = ok ? "live" : (S.open ? "MMI LOST" : "DISCONNECTED");
  l.className = "link " + (ok ? "ok" : "lost");
}
function markStale() { S.lastStatusAt = 0; updateLive(); }
setInterval(updateLive, 100);

function log(text, bad) {
  const li = document.createElement("li");
  li.textContent = new Date().toLocaleTimeString() + " " + text;
  if (bad) li.className = "bad";
  const ul = $("log");
  ul.prepend(li);
  while (ul.children.length > 30) ul.lastChild.remove();
}

// ---------- status ----------
// (a value that rounds to zero reads 0.000, not -0.000)
const fmt = (v, d = 3) => (v === null || v === undefined || !isFinite(v)) ? "—"
  : (Math.abs(v) < 0.5 * Math.pow(10, -d) ? 0 : v).toFixed(d);

function render(s) {
  const st = $("state");
  st.textContent = s.state;
  st.className = "badge " + s.state;
  const axes = ["x", "y", "z"];
  axes.forEach((a, i) => {
    $("dro-work-" + a).textContent = s.work_mm ? fmt(s.work_mm[i]) : "—";
    $("dro-mach-" + a).textContent = s.machine_mm ? fmt(s.machine_mm[i]) : "—";
    $("dro-dtg-" + a).textContent = s.distance_to_go_mm ? fmt(s.distance_to_go_mm[i]) : "—";
    const h = $("homed-" + a);
    const homed = s.homed && s.homed[i];
    h.textContent = homed ? "●" : "○";
    h.className = "homed" + (homed ? " on" : "");
    h.title = homed ? "homed" : "not homed";
  });
  $("line").textContent = s.program_line ?? "—";
  $("coords").textContent = s.coords;
  $("tool").textContent = s.tool;
  $("rpm").textContent = s.spindle ? fmt(s.spindle.actual_rpm, 0) : "—";
  const job = s.job;
  const p = job ? job.progress : 0;
  $("progress-bar").style.width = (p * 100).toFixed(1) + "%";
  $("progress").textContent = job ? `job ${job.job_id} ${job.outcome} ${(p * 100).toFixed(1)} %` : "—";
  setOvr("feed-ovr", s.feed_override);
  setOvr("rapid-ovr", s.rapid_override);
  setOvr("spindle-ovr", s.spindle_override);
  $("sw-single").checked = s.switches.single_block;
  $("sw-optional").checked = s.switches.optional_stop;
  $("sw-delete").checked = s.switches.block_delete;
  const prompt = [s.prompt, s.message, s.checking ? "checking " + s.checking : null, s.params_error, s.modal_error]
    .filter(Boolean).join(" · ");
  $("prompt").textContent = prompt;
  const al = $("alarms");
  const alarmText = s.alarms.map((a) => `${a.code}: ${a.message}`);
  if (al.dataset.text !== alarmText.join("\n")) {
    al.dataset.text = alarmText.join("\n");
    al.replaceChildren(...alarmText.map((t) => { const li = document.createElement("li"); li.textContent = t; return li; }));
  }
  // the job's program: its listing, its backplot, the current line
  const id = job ? programIdOf(job.path) : null;
  // (a running job's program is shown; once it is over, the operator's choice is)
  if (id && id !== S.listingFor && (job.outcome === "running" || !S.selected)) selectProgram(id, false);
  highlightLine(job && job.outcome === "running" ? s.program_line : null);
  // the executed path, coloured by the contour error
  if (job && job.outcome === "running" && s.work_mm) {
    if (S.trailJob !== job.job_id) { S.trail = []; S.trailJob = job.job_id; S.trailFrom = "live"; }
    const err = s.axes && s.axes.contour_err_um !== null && s.axes.contour_err_um !== undefined ? Math.abs(s.axes.contour_err_um) : null;
    const last = S.trail[S.trail.length - 1];
    const w = s.work_mm;
    if (!last || Math.hypot(last[0] - w[0], last[1] - w[1], last[2] - w[2]) > 0.05) S.trail.push([w[0], w[1], w[2], err]);
    if (S.trail.length > 20000) S.trail.splice(0, 5000);
  }
  if (job && job.outcome !== "running") {
    renderAccuracy(job);
    // once the job is over: its executed path from its trace, coloured by its
    // contour error (the live trail stays where it has no trace)
    if (S.trailJob === job.job_id && S.traceFetchedFor !== job.job_id && s.machine_mm && s.work_mm) {
      S.traceFetchedFor = job.job_id;
      const shift = [0, 1, 2].map((k) => s.machine_mm[k] - s.work_mm[k]);
      fetchTrace(job.job_id).then((t) => {
        // (a trace still being written out reads as a bad row: tried again)
        if (!t.ok && t.status !== 404) setTimeout(() => { if (S.traceFetchedFor === job.job_id) S.traceFetchedFor = null; }, 1000);
        if (!t.ok || S.trailJob !== job.job_id) return;
        S.trail = t.trace.cmd_mm.map((p, k) => [p[0] - shift[0], p[1] - shift[1], p[2] - shift[2], t.trace.contour_um[k]]);
        S.trailFrom = "trace";
        drawPlot();
      });
    }
  } else $("accuracy").textContent = "";
  drawPlot();
}

function setOvr(id, v) {
  const out = $(id + "-val");
  out.textContent = (v === null || v === undefined) ? "—" : Math.round(v * 100) + " %";
  const input = $(id);
  if (document.activeElement !== input && v !== null && v !== undefined) input.value = Math.round(v * 100);
}

function renderAccuracy(job) {
  const a = job.accuracy || {};
  const fe = (a.following_max_abs_um || []).map((v) => v.toFixed(1)).join(" / ");
  $("accuracy").textContent = `job ${job.job_id} ${job.outcome}: contour max ${fmt(a.contour_max_abs_um, 1)} µm, RMS ${fmt(a.contour_rms_um, 1)} µm; following max X/Y/Z ${fe} µm`;
}

// ---------- programs ----------
function programIdOf(path) {
  const m = /web\/programs\/([0-9a-f]{64})\.ngc$/.exec(path || "");
  return m ? m[1] : null;
}

function authHeaders() {
  return S.token ? { Authorization: "Bearer " + S.token } : {};
}

async function loadPrograms() {
  const r = await fetch("/api/programs", { headers: authHeaders() });
  if (!r.ok) return;
  S.programs = (await r.json()).programs;
  const ul = $("programs");
  ul.replaceChildren(...S.programs.map((p) => {
    const li = document.createElement("li");
    li.textContent = `${p.name} (${p.lines} lines)`;
    li.dataset.id = p.id;
    if (p.id === S.selected) li.className = "selected";
    li.onclick = () => selectProgram(p.id, true);
    return li;
  }));
}

async function selectProgram(id, byHand) {
  S.selected = id; S.listingFor = id;
  for (const li of $("programs").children) li.classList.toggle("selected", li.dataset.id === id);
  const r = await fetch("/api/programs/" + id, { headers: authHeaders() });
  if (!r.ok) { if (byHand) log("program: " + r.status, true); return; }
  const text = await r.text();
  const lines = text.split("\n");
  const ol = $("listing");
  ol.replaceChildren(...lines.map((t) => { const li = document.createElement("li"); li.textContent = t || " "; return li; }));
  S.plan = parseGcode(lines); S.planFor = id; S.trail = []; S.trailJob = null;
  fitPlot(); drawPlot();
}

let currentLine = null;
function highlightLine(n) {
  if (n === currentLine) return;
  const ol = $("listing");
  if (currentLine && ol.children[currentLine - 1]) ol.children[currentLine - 1].classList.remove("current");
  currentLine = n;
  const li = n ? ol.children[n - 1] : null;
  if (li) { li.classList.add("current"); li.scrollIntoView({ block: "center" }); }
}

async function upload() {
  const f = $("file").files[0];
  if (!f) { log("choose a program file first", true); return; }
  const r = await fetch("/api/programs", {
    method: "POST", body: f,
    headers: { ...authHeaders(), "X-File-Name": f.name.replace(/[^\x20-\x7e]/g, "_") },
  });
  const j = await r.json().catch(() => ({ message: "HTTP " + r.status }));
  if (!r.ok) { log("upload refused: " + j.message, true); return; }
  log(`uploaded ${j.program.name}`);
  await loadPrograms();
  selectProgram(j.program.id, true);
}

// ---------- G-code backplot (a plain reading: G0-G3, G90/G91, G17 arcs, R or IJ, P turns) ----------
function parseGcode(lines) {
  const segs = []; // [x0,y0,z0,x1,y1,z1,rapid,line]
  let pos = [0, 0, 0], motion = 0, abs = true;
  lines.forEach((raw, i) => {
    const text = raw.replace(/\([^)]*\)/g, "").replace(/;.*/, "").toUpperCase();
    const words = {}; const gs = [];
    for (const m of text.matchAll(/([A-Z])\s*([-+]?[0-9]*\.?[0-9]+)/g)) {
      if (m[1] === "G") gs.push(parseFloat(m[2])); else words[m[1]] = parseFloat(m[2]);
    }
    for (const g of gs) {
      if (g === 0 || g === 1 || g === 2 || g === 3) motion = g;
      if (g === 90) abs = true; if (g === 91) abs = false;
    }
    if (gs.some((g) => g === 28 || g === 53 || g === 10 || g === 92 || g === 43)) return;
    if (!("X" in words || "Y" in words || "Z" in words)) return;
    const t = [0, 1, 2].map((k) => { const w = "XYZ"[k]; return w in words ? (abs ? words[w] : pos[k] + words[w]) : pos[k]; });
    if (motion <= 1) { segs.push([...pos, ...t, motion === 0, i + 1]); }
    else {
      let cx, cy;
      if ("R" in words) {
        const dx = t[0] - pos[0], dy = t[1] - pos[1], d = Math.hypot(dx, dy), r = Math.abs(words.R);
        const h = Math.sqrt(Math.max(r * r - d * d / 4, 0));
        let s = (motion === 2) ? -1 : 1; if (words.R < 0) s = -s;
        cx = pos[0] + dx / 2 - s * h * dy / d; cy = pos[1] + dy / 2 + s * h * dx / d;
      } else { cx = pos[0] + (words.I || 0); cy = pos[1] + (words.J || 0); }
      const r = Math.hypot(pos[0] - cx, pos[1] - cy);
      let a0 = Math.atan2(pos[1] - cy, pos[0] - cx), a1 = Math.atan2(t[1] - cy, t[0] - cx);
      const turns = Math.max(1, Math.round(words.P || 1));
      let sweep = a1 - a0;
      if (motion === 2) { if (sweep >= -1e-9) sweep -= 2 * Math.PI; sweep -= 2 * Math.PI * (turns - 1); }
      else { if (sweep <= 1e-9) sweep += 2 * Math.PI; sweep += 2 * Math.PI * (turns - 1); }
      const n = Math.max(8, Math.ceil(Math.abs(sweep) * r / 0.5));
      let p = pos.slice();
      for (let k = 1; k <= n; k++) {
        const a = a0 + sweep * k / n;
        const q = [cx + r * Math.cos(a), cy + r * Math.sin(a), pos[2] + (t[2] - pos[2]) * k / n];
        segs.push([...p, ...q, false, i + 1]); p = q;
      }
    }
    pos = t;
  });
  return segs;
}

const V = { yaw: -0.6, pitch: 0.9, zoom: 1, cx: 0, cy: 0, cz: 0 };
const PRESETS = { iso: [-0.6, 0.9], top: [0, 0], front: [0, Math.PI / 2] };

function project(p, w, h) {
  const x = p[0] - V.cx, y = p[1] - V.cy, z = p[2] - V.cz;
  const cyw = Math.cos(V.yaw), syw = Math.sin(V.yaw);
  const x1 = x * cyw - y * syw, y1 = x * syw + y * cyw;
  const cp = Math.cos(V.pitch), sp = Math.sin(V.pitch);
  const y2 = y1 * cp - z * sp;
  return [w / 2 + x1 * V.zoom, h / 2 - y2 * V.zoom];
}

function fitPlot() {
  const pts = [];
  (S.plan || []).forEach((s) => { pts.push(s.slice(0, 3)); pts.push(s.slice(3, 6)); });
  if (!pts.length) return;
  const lo = [0, 1, 2].map((k) => Math.min(...pts.map((p) => p[k])));
  const hi = [0, 1, 2].map((k) => Math.max(...pts.map((p) => p[k])));
  V.cx = (lo[0] + hi[0]) / 2; V.cy = (lo[1] + hi[1]) / 2; V.cz = (lo[2] + hi[2]) / 2;
  const c = $("backplot");
  const span = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1);
  V.zoom = 0.8 * Math.min(c.clientWidth || 400, c.clientHeight || 300) / span;
}

function errColour(e) {
  if (e === null) return "#9ab";
  return e < 5 ? "#3c3" : e < 20 ? "#ec3" : "#f33";
}

function drawPlot() {
  const c = $("backplot");
  const w = c.clientWidth, h = c.clientHeight;
  if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
  const g = c.getContext("2d");
  g.clearRect(0, 0, w, h);
  // axes at the work origin
  const o = project([0, 0, 0], w, h);
  [[10, 0, 0, "#c44"], [0, 10, 0, "#4c4"], [0, 0, 10, "#48f"]].forEach(([x, y, z, col]) => {
    const p = project([x, y, z], w, h); g.strokeStyle = col; g.beginPath(); g.moveTo(...o); g.lineTo(...p); g.stroke();
  });
  if (S.plan) {
    g.lineWidth = 1;
    for (const s of S.plan) {
      g.strokeStyle = s[6] ? "#3a4a5a" : "#5b7390";
      g.setLineDash(s[6] ? [4, 4] : []);
      g.beginPath(); g.moveTo(...project(s, w, h)); g.lineTo(...project(s.slice(3), w, h)); g.stroke();
    }
    g.setLineDash([]);
  }
  g.lineWidth = 2.5;
  for (let i = 1; i < S.trail.length; i++) {
    g.strokeStyle = errColour(S.trail[i][3]);
    g.beginPath(); g.moveTo(...project(S.trail[i - 1], w, h)); g.lineTo(...project(S.trail[i], w, h)); g.stroke();
  }
  g.lineWidth = 1;
  const s = S.status;
  if (s && s.work_mm) {
    const p = project(s.work_mm, w, h);
    g.fillStyle = live() ? "#ff0" : "#666";
    g.beginPath(); g.arc(p[0], p[1], 6, 0, 2 * Math.PI); g.fill();
    g.fillStyle = "#ccc"; g.font = "12px monospace";
    g.fillText(`tool ${fmt(s.work_mm[0])} ${fmt(s.work_mm[1])} ${fmt(s.work_mm[2])}`, 8, h - 8);
  }
}

(function plotControls() {
  const c = $("backplot");
  let drag = null;
  c.addEventListener("pointerdown", (e) => { drag = [e.clientX, e.clientY]; c.setPointerCapture(e.pointerId); });
  c.addEventListener("pointermove", (e) => {
    if (!drag) return;
    V.yaw += (e.clientX - drag[0]) * 0.01; V.pitch = Math.min(Math.PI, Math.max(0, V.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY]; drawPlot();
  });
  c.addEventListener("pointerup", () => { drag = null; });
  c.addEventListener("wheel", (e) => { e.preventDefault(); V.zoom *= e.deltaY < 0 ? 1.15 : 1 / 1.15; drawPlot(); }, { passive: false });
  document.querySelectorAll("[data-viewpreset]").forEach((b) => b.onclick = () => {
    [V.yaw, V.pitch] = PRESETS[b.dataset.viewpreset]; drawPlot();
  });
  $("plot-fit").onclick = () => { fitPlot(); drawPlot(); };
  window.addEventListener("resize", () => { drawPlot(); drawTrace(); });
})();

// ---------- history, offsets, tools ----------
function cell(tr, text, tag = "td") { const c = document.createElement(tag); c.textContent = text; tr.append(c); }

function renderJobs() {
  const t = $("jobs");
  const head = document.createElement("tr");
  ["job", "program", "outcome", "progress", "contour max µm", "contour RMS µm", "following max X/Y/Z µm", "alarms"].forEach((h) => cell(head, h, "th"));
  const rows = S.jobs.map((j) => {
    const tr = document.createElement("tr");
    const id = programIdOf(j.path);
    const prog = id ? (S.programs.find((p) => p.id === id) || { name: id.slice(0, 10) }).name : (j.mdi ? "MDI " + j.mdi : j.path.split("/").pop());
    const a = j.accuracy || {};
    cell(tr, j.job_id); cell(tr, prog); cell(tr, j.outcome);
    cell(tr, j.planned_path_mm > 0 ? (100 * Math.min(1, j.outcome === "completed" ? 1 : j.path_mm / j.planned_path_mm)).toFixed(0) + " %" : "—");
    cell(tr, fmt(a.contour_max_abs_um, 1)); cell(tr, fmt(a.contour_rms_um, 1));
    cell(tr, (a.following_max_abs_um || []).map((v) => v.toFixed(1)).join(" / "));
    cell(tr, (j.alarms || []).length);
    tr.title = (j.alarms || []).join("\n");
    tr.dataset.job = j.job_id;
    tr.className = "pick" + (j.job_id === S.jobSelected ? " selected" : "");
    tr.onclick = () => selectJob(j.job_id);
    return tr;
  });
  t.replaceChildren(head, ...rows);
}

// ---------- a job's trace: contour and following error against time ----------
async function fetchTrace(jobId) {
  try {
    const r = await fetch(`/api/jobs/${jobId}/trace`, { headers: authHeaders() });
    const j = await r.json().catch(() => ({ message: "HTTP " + r.status }));
    return r.ok ? { ok: true, trace: j } : { ok: false, status: r.status, message: j.message || "HTTP " + r.status };
  } catch (e) {
    return { ok: false, message: String(e) };
  }
}

async function selectJob(jobId) {
  S.jobSelected = jobId;
  for (const tr of $("jobs").querySelectorAll("tr[data-job]")) tr.classList.toggle("selected", Number(tr.dataset.job) === jobId);
  $("trace-figures").textContent = `job ${jobId}: reading its trace …`;
  const t = await fetchTrace(jobId);
  if (S.jobSelected !== jobId) return;
  S.trace = t.ok ? t.trace : null;
  if (!t.ok) { $("trace-figures").textContent = `job ${jobId}: ${t.message}`; drawTrace(); return; }
  const tr = t.trace;
  const dur = tr.time_s.length ? tr.time_s[tr.time_s.length - 1] : 0;
  $("trace-figures").textContent = `job ${jobId} trace: ${tr.rows} cycles, ${dur.toFixed(2)} s; contour max ${fmt(tr.contour_max_abs_um, 1)} µm; following max X/Y/Z ${tr.following_max_abs_um.map((v) => v.toFixed(1)).join(" / ")} µm`;
  drawTrace();
}

function drawTrace() {
  const c = $("trace-plot");
  const w = c.clientWidth, h = c.clientHeight;
  if (!w || !h) return;
  if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
  const g = c.getContext("2d");
  g.clearRect(0, 0, w, h);
  const t = S.trace;
  if (!t || !t.time_s.length) return;
  const left = 54, right = 8, top = 8, bottom = 20;
  const t0 = t.time_s[0], t1 = Math.max(t.time_s[t.time_s.length - 1], t0 + 1e-3);
  const top_um = Math.max(t.contour_max_abs_um, ...t.following_max_abs_um, 1) * 1.05;
  const X = (v) => left + (v - t0) / (t1 - t0) * (w - left - right);
  const Y = (v) => h - bottom - v / top_um * (h - top - bottom);
  g.strokeStyle = "#445"; g.fillStyle = "#99a"; g.font = "11px monospace"; g.lineWidth = 1;
  for (let k = 0; k <= 4; k++) {
    const v = top_um * k / 4;
    g.beginPath(); g.moveTo(left, Y(v)); g.lineTo(w - right, Y(v)); g.stroke();
    g.fillText(v.toFixed(0) + (k === 4 ? " µm" : ""), 4, Y(v) + (k === 4 ? 10 : 4));
  }
  g.fillText(`${t0.toFixed(1)} s`, left, h - 5);
  g.fillText(`${t1.toFixed(1)} s`, w - right - 50, h - 5);
  const series = [[t.following_um[0], "#f55"], [t.following_um[1], "#5d5"], [t.following_um[2], "#59f"], [t.contour_um, "#eee"]];
  g.lineWidth = 1.2;
  for (const [ys, col] of series) {
    g.strokeStyle = col; g.beginPath();
    let pen = false;
    ys.forEach((v, k) => {
      if (v === null || v === undefined) { pen = false; return; }
      const x = X(t.time_s[k]), y = Y(v);
      if (pen) g.lineTo(x, y); else g.moveTo(x, y);
      pen = true;
    });
    g.stroke();
  }
}

// the offsets last read: the work-offset form starts from the system's values
S.offsets = null;
function fillOffsetForm() {
  if (!S.offsets) return;
  const sys = S.offsets.systems[parseInt($("ofs-sys").value, 10) - 1];
  if (!sys) return;
  ["x", "y", "z"].forEach((a, i) => { if (document.activeElement !== $("ofs-" + a)) $("ofs-" + a).value = sys.origin_mm[i]; });
}
function renderOffsets(o) {
  S.offsets = o; fillOffsetForm();
  const t = $("offsets");
  const head = document.createElement("tr");
  ["system", "X", "Y", "Z", "rotation °"].forEach((h) => cell(head, h, "th"));
  const rows = o.systems.map((s) => {
    const tr = document.createElement("tr");
    cell(tr, s.coords + (s.active ? " ●" : "")); s.origin_mm.forEach((v) => cell(tr, fmt(v))); cell(tr, fmt(s.rotation_deg, 2));
    return tr;
  });
  t.replaceChildren(head, ...rows);
}

function renderTools(tools) {
  const t = $("tools");
  const head = document.createElement("tr");
  ["tool", "length mm", "diameter mm"].forEach((h) => cell(head, h, "th"));
  t.replaceChildren(head, ...tools.map((x) => { const tr = document.createElement("tr"); cell(tr, x.number); cell(tr, fmt(x.length_mm)); cell(tr, fmt(x.diameter_mm)); return tr; }));
}

// ---------- jog ----------
function startJog(axis, dir) {
  const mode = $("jog-mode").value;
  if (mode !== "cont") { cmd({ command: "jog_step", axis, distance_mm: dir * parseFloat(mode) }); return; }
  const speed = dir * Math.abs(parseFloat($("jog-speed").value) || 0);
  stopJog();
  S.jogAxis = axis;
  const tick = () => send({ t: "jog", axis, speed_mm_per_min: speed });
  tick();
  S.jogTimer = setInterval(tick, JOG_RENEW_MS);
}
function stopJog() {
  if (S.jogTimer) { clearInterval(S.jogTimer); S.jogTimer = null; }
  if (S.jogAxis && S.open) S.ws.send(JSON.stringify({ t: "jog", axis: S.jogAxis, speed_mm_per_min: 0 }));
  S.jogAxis = null;
}
document.querySelectorAll(".jogb").forEach((b) => {
  b.addEventListener("pointerdown", (e) => { e.preventDefault(); startJog(b.dataset.axis, parseFloat(b.dataset.dir)); });
  ["pointerup", "pointerleave", "pointercancel"].forEach((ev) => b.addEventListener(ev, () => { if (S.jogTimer) stopJog(); }));
});
window.addEventListener("blur", () => { if (S.jogTimer) stopJog(); });
document.addEventListener("visibilitychange", () => { if (document.hidden && S.jogTimer) stopJog(); });

// ---------- buttons ----------
function on(id, f) { $(id).addEventListener("click", f); }
on("estop", () => {
  // over the socket; without one, over HTTP
  if (!send({ t: "cmd", id: S.nextId++, request: { command: "e_stop" } })) {
    fetch("/api/command", { method: "POST", headers: { ...authHeaders(), "Content-Type": "application/json" }, body: JSON.stringify({ command: "e_stop" }) })
      .then((r) => r.json()).then((j) => log(j.message, !j.ok)).catch((e) => log("E-stop not sent: " + e, true));
  }
});
on("login", () => {
  S.token = $("token").value.trim(); $("token").value = "";
  sessionStorage.setItem("softnc-token", S.token);
  send({ t: "auth", token: S.token });
});
$("token").addEventListener("keydown", (e) => { if (e.key === "Enter") $("login").click(); });
on("btn-on", () => cmd({ command: "machine_on" }));
on("btn-off", () => cmd({ command: "machine_off" }));
on("btn-reset", () => cmd({ command: "reset" }));
on("btn-home", () => cmd({ command: "home" }));
on("btn-hold", () => cmd({ command: "hold" }));
on("btn-resume", () => cmd({ command: "resume" }));
on("btn-step", () => cmd({ command: "step" }));
on("btn-abort", () => cmd({ command: "abort" }));
on("btn-upload", upload);
on("btn-run", () => {
  if (!S.selected) { log("select a program first", true); return; }
  S.trail = []; S.trailJob = null;
  send({ t: "run", id: S.nextId++, program: S.selected });
});
on("btn-touch", () => cmd({ command: "touch_off", axis: $("touch-axis").value, value_mm: parseFloat($("touch-value").value) || 0 }));
function sendMdi() {
  const text = $("mdi").value.trim();
  if (!text) return;
  cmd({ command: "mdi", blocks: text });
  const li = document.createElement("li"); li.textContent = text; li.onclick = () => { $("mdi").value = text; };
  $("mdi-history").prepend(li);
  $("mdi").value = "";
}
on("btn-mdi", sendMdi);
$("mdi").addEventListener("keydown", (e) => { if (e.key === "Enter") sendMdi(); });
on("btn-tables", () => { cmd({ command: "offsets" }); cmd({ command: "tools" }); });
// a work offset set as LinuxCNC sets it: G10 L2 P<n> (through MDI, checked as every block)
on("btn-ofs-set", () => {
  const n = parseInt($("ofs-sys").value, 10);
  const v = ["x", "y", "z"].map((a) => parseFloat($("ofs-" + a).value));
  if (v.some((x) => !isFinite(x))) { log("work offset: a value is not a number", true); return; }
  S.offsetSetId = cmd({ command: "mdi", blocks: `G10 L2 P${n} X${v[0]} Y${v[1]} Z${v[2]}` });
});
$("ofs-sys").addEventListener("change", fillOffsetForm);
on("btn-tool-set", () => cmd({ command: "tool_set", tool: parseInt($("tool-no").value, 10), length_mm: parseFloat($("tool-len").value) || 0, diameter_mm: parseFloat($("tool-dia").value) || 0 }));
[["sw-single", "single_block"], ["sw-optional", "optional_stop"], ["sw-delete", "block_delete"]].forEach(([id, c]) =>
  $(id).addEventListener("change", (e) => cmd({ command: c, on: e.target.checked })));
[["feed-ovr", "feed_override"], ["rapid-ovr", "rapid_override"], ["spindle-ovr", "spindle_override"]].forEach(([id, c]) =>
  $(id).addEventListener("change", (e) => cmd({ command: c, fraction: parseFloat(e.target.value) / 100 })));
document.querySelectorAll(".tab").forEach((b) => b.onclick = () => {
  document.querySelectorAll(".tab").forEach((x) => x.classList.toggle("active", x === b));
  document.querySelectorAll(".view").forEach((v) => v.classList.toggle("active", v.id === "view-" + b.dataset.view));
  if (b.dataset.view === "tables") $("btn-tables").click();
  drawPlot(); drawTrace();
});

loadPrograms();
connect();
