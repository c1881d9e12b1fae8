// The mpm job service's page: the job list (live progress), a job's page (metrics,
// comparisons, stability diagnostics, frame pictures, error against run time, scene,
// cancel) and a form to submit a scene. Plain JavaScript, no libraries; every value from
// the service is put in the page as text, never as HTML.
"use strict";

const $ = (id) => document.getElementById(id);
const TOKEN_KEY = "mpm-token";
let token = localStorage.getItem(TOKEN_KEY) || "";
// What the current view started (streams, timers, object URLs), stopped when it changes.
let viewAbort = new AbortController();
let timers = [];
let frameUrl = null;

function headers(extra) {
  const h = Object.assign({}, extra || {});
  if (token) h["Authorization"] = "Bearer " + token;
  return h;
}

function notice(text) {
  const n = $("notice");
  n.textContent = text || "";
  n.hidden = !text;
}

// A call to the API: the parsed JSON body (or null), and the status.
async function api(path, options) {
  const opts = Object.assign({}, options || {});
  opts.headers = headers(opts.headers);
  const response = await fetch(path, opts);
  let body = null;
  const type = response.headers.get("content-type") || "";
  if (type.startsWith("application/json")) body = await response.json();
  if (response.status === 401) notice("The service needs a token: enter it above.");
  return { status: response.status, ok: response.ok, body };
}

// Follows a job's server-sent events through fetch (EventSource cannot send the token),
// calling onJob with each job it reports until the stream ends or the signal aborts.
async function follow(id, onJob, signal) {
  const response = await fetch(`/v1/jobs/${encodeURIComponent(id)}/events`, {
    headers: headers({ Accept: "text/event-stream" }),
    signal,
  });
  if (!response.ok || !response.body) return;
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let buffer = "";
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buffer += decoder.decode(value, { stream: true }).replace(/\r\n/g, "\n");
    let cut;
    while ((cut = buffer.indexOf("\n\n")) >= 0) {
      const block = buffer.slice(0, cut);
      buffer = buffer.slice(cut + 2);
      const data = block
        .split("\n")
        .filter((l) => l.startsWith("data:"))
        .map((l) => l.slice(5).trimStart())
        .join("\n");
      if (data) {
        try {
          onJob(JSON.parse(data));
        } catch (e) {
          /* a keep-alive or a line that is not a job */
        }
      }
    }
  }
}

const FINAL = ["succeeded", "failed", "cancelled"];

function fmt(x, digits) {
  if (x === null || x === undefined) return "";
  if (typeof x !== "number") return String(x);
  if (!Number.isFinite(x)) return String(x);
  if (x !== 0 && (Math.abs(x) < 1e-3 || Math.abs(x) >= 1e6)) return x.toExponential(digits || 3);
  return Number(x.toPrecision(digits || 4)).toString();
}

function seconds(s) {
  return s === null || s === undefined ? "" : fmt(s, 3) + " s";
}

function cell(row, text, cls) {
  const td = document.createElement("td");
  if (text instanceof Node) td.appendChild(text);
  else td.textContent = text === undefined || text === null ? "" : String(text);
  if (cls) td.className = cls;
  row.appendChild(td);
  return td;
}

function statusBadge(status) {
  const s = document.createElement("span");
  s.className = "status " + status;
  s.textContent = status;
  return s;
}

function progressText(job) {
  const p = job.progress || {};
  let text = `${((p.fraction || 0) * 100).toFixed(1)}%`;
  if (p.stage) text += ` (${p.stage})`;
  if (job.status === "running" && p.eta_seconds != null) text += `, ${fmt(p.eta_seconds, 2)} s left`;
  return text;
}

// ---- job list ----

function jobRow(job) {
  const tr = document.createElement("tr");
  tr.dataset.id = job.id;
  tr.dataset.status = job.status;
  const link = document.createElement("a");
  link.href = `#/jobs/${job.id}`;
  link.textContent = job.name;
  cell(tr, link);
  cell(tr, statusBadge(job.status), "job-status");
  const bar = document.createElement("progress");
  bar.max = 1;
  bar.value = (job.progress && job.progress.fraction) || 0;
  const wrap = document.createElement("span");
  wrap.appendChild(bar);
  wrap.append(" " + progressText(job));
  cell(tr, wrap, "job-progress");
  cell(tr, job.particles);
  cell(tr, seconds(job.progress && job.progress.wall_seconds));
  cell(tr, job.metrics && job.metrics.error != null ? fmt(job.metrics.error) : "");
  cell(tr, job.created_at);
  cell(tr, job.owner || "");
  tr.addEventListener("click", (e) => {
    if (e.target.tagName !== "A") location.hash = `#/jobs/${job.id}`;
  });
  return tr;
}

// Jobs whose events this view follows, by id.
let followed = new Map();
const MAX_STREAMS = 3; // browsers allow six connections per host; keep some for the rest

async function refreshJobs(signal) {
  // The API lists in submission order: the newest 200 are the last page.
  let r = await api("/v1/jobs?limit=200", { signal });
  if (r.ok && r.body && r.body.total > 200) {
    r = await api(`/v1/jobs?limit=200&offset=${r.body.total - 200}`, { signal });
  }
  if (!r.ok || !r.body) return;
  const tbody = $("jobs").querySelector("tbody");
  const jobs = r.body.jobs.slice().reverse(); // newest first
  tbody.replaceChildren(...jobs.map(jobRow));
  $("jobs-empty").hidden = jobs.length > 0;
  for (const job of jobs) {
    if (job.status === "running" && !followed.has(job.id) && followed.size < MAX_STREAMS) {
      followed.set(job.id, true);
      follow(
        job.id,
        (j) => {
          const old = tbody.querySelector(`tr[data-id="${CSS.escape(j.id)}"]`);
          if (old) old.replaceWith(jobRow(j));
        },
        signal,
      )
        .catch(() => {})
        .finally(() => followed.delete(job.id));
    }
  }
}

function showJobs(signal) {
  followed = new Map();
  const tick = () => refreshJobs(signal).catch(() => {});
  tick();
  timers.push(setInterval(tick, 2000));
}

// ---- one job ----

function kvRows(table, pairs) {
  const tbody = table.querySelector("tbody");
  tbody.replaceChildren(
    ...pairs
      .filter(([, v]) => v !== undefined && v !== null && v !== "")
      .map(([k, v]) => {
        const tr = document.createElement("tr");
        const th = document.createElement("th");
        th.textContent = k;
        tr.appendChild(th);
        cell(tr, typeof v === "number" ? fmt(v) : v);
        return tr;
      }),
  );
}

// Where a job submitted with `from` started: the job, the stage and the simulated time.
function startedFrom(job) {
  const f = job.from;
  if (!f) return null;
  const stage = f.stage ? `, at stage ${f.stage}` : ", its latest checkpoint";
  return `job ${f.job}${stage} (t = ${fmt(f.time)} s)`;
}

function showMetrics(job) {
  const m = job.metrics || {};
  kvRows($("job-metrics"), [
    ["outcome", m.outcome],
    ["particles", job.particles],
    ["steps", m.steps != null ? m.steps : job.progress.steps],
    ["simulated time", m.simulated_time != null ? fmt(m.simulated_time) + " s" : ""],
    ["wall time", seconds(m.wall_seconds != null ? m.wall_seconds : job.progress.wall_seconds)],
    ["particle-steps / s", m.particle_steps_per_second],
    ["bytes / particle", m.bytes_per_particle],
    ["frames", m.frames],
    ["threads", m.threads],
    ["error", m.error],
    ["error kind", m.error_kind],
    ["reference value", m.reference_value],
    ["measured value", m.measured_value],
    ["resumed from step", m.resumed_from_step],
    ["started from", startedFrom(job)],
    ["worker", job.worker],
    ["attempts", job.attempts],
  ]);
  const comparisons = Array.isArray(m.comparisons) ? m.comparisons : [];
  $("job-comparisons").querySelector("tbody").replaceChildren(
    ...comparisons.map((c) => {
      const tr = document.createElement("tr");
      cell(tr, c.quantity);
      cell(tr, fmt(c.measured));
      cell(tr, fmt(c.reference));
      cell(tr, fmt(c.relative_difference));
      return tr;
    }),
  );
  $("job-comparisons").hidden = comparisons.length === 0;
  $("job-no-comparisons").hidden = comparisons.length > 0;
  const c = m.conservation || {};
  const ledger = m.energy_ledger || {};
  const pairs = [
    ["energy drift", m.energy_drift],
    ["largest energy drift", m.max_energy_drift],
    ["boundary work", m.boundary_work],
    ["min det F", m.min_det_f],
    ["max speed", m.max_speed != null ? fmt(m.max_speed) + " m/s" : ""],
    ["max momentum", m.max_momentum],
    ["mass change", c.mass_change],
    ["momentum change", c.momentum_change],
    ["angular momentum change", c.angular_momentum_change],
    ["external forces", c.external_forces === undefined ? "" : String(c.external_forces)],
  ];
  for (const [k, v] of Object.entries(ledger)) pairs.push([`energy to ${k.replace(/_/g, " ")}`, v]);
  if (m.diagnostic) {
    pairs.push(["stopped on", JSON.stringify(m.diagnostic)]);
  }
  kvRows($("job-stability"), pairs);
}

function showJobHead(job) {
  $("job-title").textContent = `${job.name} (${job.id})`;
  $("job-status").replaceWith(Object.assign(statusBadge(job.status), { id: "job-status" }));
  $("job-status").dataset.status = job.status;
  $("job-progress").value = (job.progress && job.progress.fraction) || 0;
  $("job-progress-text").textContent = progressText(job);
  $("job-cancel").hidden = FINAL.includes(job.status);
  const f = $("job-failure");
  f.hidden = !job.failure;
  f.textContent = job.failure ? `Failure: ${job.failure.message || JSON.stringify(job.failure)}` : "";
  showMetrics(job);
}

async function showFrame(id, signal) {
  const field = $("frame-field").value || "x";
  const frame = $("frame-index").value;
  $("frame-label").textContent = `${frame} of 0–${$("frame-index").max}`;
  const response = await fetch(
    `/v1/jobs/${encodeURIComponent(id)}/frames/${frame}?field=${encodeURIComponent(field)}`,
    { headers: headers(), signal },
  );
  const err = $("frame-error");
  if (!response.ok) {
    let message = `HTTP ${response.status}`;
    try {
      message = (await response.json()).error.message;
    } catch (e) {}
    err.textContent = message;
    err.hidden = false;
    return;
  }
  err.hidden = true;
  const blob = await response.blob();
  if (frameUrl) URL.revokeObjectURL(frameUrl);
  frameUrl = URL.createObjectURL(blob);
  $("frame").src = frameUrl;
}

function setUpFrames(id, job, scene, signal) {
  const frames = (job.metrics && job.metrics.frames) || 0;
  const slider = $("frame-index");
  slider.max = Math.max(frames - 1, 0);
  slider.value = slider.max;
  const fields = ((scene && scene.output && scene.output.fields) || []).filter((f) => f !== "x");
  fields.push("x");
  const select = $("frame-field");
  select.replaceChildren(
    ...fields.map((f) => Object.assign(document.createElement("option"), { value: f, textContent: f })),
  );
  $("frame-controls").hidden = frames === 0;
  $("frame").hidden = frames === 0;
  if (frames > 0) {
    const draw = () => showFrame(id, signal).catch(() => {});
    select.onchange = draw;
    slider.onchange = draw;
    slider.oninput = () => ($("frame-label").textContent = `${slider.value} of 0–${slider.max}`);
    draw();
  }
}

// Error against run time of the finished jobs with this job's name, log-log, as SVG.
async function showStudy(job, signal) {
  const box = $("study");
  box.replaceChildren();
  const r = await api("/v1/jobs?status=succeeded&limit=1000", { signal });
  if (!r.ok) return;
  const points = r.body.jobs
    .filter((j) => j.name === job.name && j.metrics && j.metrics.error > 0 && j.metrics.wall_seconds > 0)
    .map((j) => ({ id: j.id, t: j.metrics.wall_seconds, e: j.metrics.error }));
  if (points.length === 0) {
    box.textContent = "No finished job of this scene has an error against a reference.";
    return;
  }
  const NS = "http://www.w3.org/2000/svg";
  const W = 480, H = 300, L = 62, B = 40, T = 12, R = 12;
  const lt = points.map((p) => Math.log10(p.t)), le = points.map((p) => Math.log10(p.e));
  const span = (v) => {
    let lo = Math.min(...v), hi = Math.max(...v);
    if (hi - lo < 0.2) { lo -= 0.1; hi += 0.1; }
    const pad = 0.05 * (hi - lo); // keeps the end points' rings inside the axes
    return [lo - pad, hi + pad];
  };
  const [t0, t1] = span(lt), [e0, e1] = span(le);
  const X = (t) => L + ((Math.log10(t) - t0) / (t1 - t0)) * (W - L - R);
  const Y = (e) => T + (1 - (Math.log10(e) - e0) / (e1 - e0)) * (H - T - B);
  const svg = document.createElementNS(NS, "svg");
  svg.setAttribute("width", W);
  svg.setAttribute("height", H);
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  const add = (tag, attrs, text) => {
    const el = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
    if (text !== undefined) el.textContent = text;
    svg.appendChild(el);
    return el;
  };
  add("line", { class: "axis", x1: L, y1: H - B, x2: W - R, y2: H - B });
  add("line", { class: "axis", x1: L, y1: T, x2: L, y2: H - B });
  add("text", { x: (L + W - R) / 2, y: H - 6, "text-anchor": "middle" }, "wall time, s (log)");
  add("text", { x: 12, y: (T + H - B) / 2, transform: `rotate(-90 12 ${(T + H - B) / 2})`, "text-anchor": "middle" }, "error (log)");
  for (const [v, x, y, anchor] of [
    [10 ** t0, L, H - B + 14, "start"], [10 ** t1, W - R, H - B + 14, "end"],
  ]) add("text", { x, y, "text-anchor": anchor }, fmt(v, 2));
  add("text", { x: L - 4, y: H - B, "text-anchor": "end" }, fmt(10 ** e0, 2));
  add("text", { x: L - 4, y: T + 8, "text-anchor": "end" }, fmt(10 ** e1, 2));
  // Pareto front: no other job is both faster and more accurate.
  const front = points
    .filter((p) => !points.some((q) => q !== p && q.t <= p.t && q.e <= p.e && (q.t < p.t || q.e < p.e)))
    .sort((a, b) => a.t - b.t);
  if (front.length > 1) add("polyline", { class: "front", points: front.map((p) => `${X(p.t)},${Y(p.e)}`).join(" ") });
  for (const p of points) {
    const dot = add("circle", { class: "point", cx: X(p.t), cy: Y(p.e), r: 4 });
    const title = document.createElementNS(NS, "title");
    title.textContent = `${p.id}: error ${fmt(p.e)}, ${fmt(p.t)} s`;
    dot.appendChild(title);
    if (p.id === job.id) add("circle", { class: "this", cx: X(p.t), cy: Y(p.e), r: 8 });
  }
  box.appendChild(svg);
}

async function showJob(id, signal) {
  $("job-scene").textContent = "";
  $("frame").removeAttribute("src");
  $("frame-error").hidden = true;
  const r = await api(`/v1/jobs/${encodeURIComponent(id)}`, { signal });
  if (!r.ok) {
    $("job-title").textContent = r.body && r.body.error ? r.body.error.message : `HTTP ${r.status}`;
    return;
  }
  let job = r.body;
  showJobHead(job);
  const s = await api(`/v1/jobs/${encodeURIComponent(id)}/scene`, { signal });
  const scene = s.ok ? s.body : null;
  $("job-scene").textContent = scene ? JSON.stringify(scene, null, 2) : "";
  const finish = (j) => {
    setUpFrames(id, j, scene, signal);
    showStudy(j, signal).catch(() => {});
  };
  $("job-cancel").onclick = async () => {
    const c = await api(`/v1/jobs/${encodeURIComponent(id)}`, { method: "DELETE" });
    if (c.ok) showJobHead(c.body);
    else notice(c.body && c.body.error ? c.body.error.message : `HTTP ${c.status}`);
  };
  if (FINAL.includes(job.status)) {
    finish(job);
    return;
  }
  setUpFrames(id, job, scene, signal);
  await follow(
    id,
    (j) => {
      job = j;
      showJobHead(j);
    },
    signal,
  ).catch(() => {});
  if (!signal.aborted && FINAL.includes(job.status)) finish(job);
}

// ---- submitting ----

function showSubmitErrors(body, status) {
  const box = $("submit-errors");
  const err = (body && body.error) || { message: `HTTP ${status}` };
  $("submit-message").textContent = err.message;
  const list = $("submit-problems");
  // Text that is not JSON at all is a problem of the whole document, `$`.
  const problems = err.problems && err.problems.length ? err.problems
    : err.code === "bad_json" ? [{ path: "$", message: err.message }] : [];
  list.replaceChildren(
    ...problems.map((p) => {
      const li = document.createElement("li");
      const code = document.createElement("code");
      code.className = "problem-path";
      code.textContent = p.path;
      li.appendChild(code);
      li.append(": " + p.message);
      return li;
    }),
  );
  box.hidden = false;
}

function setUpSubmit() {
  $("scene-file").addEventListener("change", async (e) => {
    const file = e.target.files[0];
    if (file) $("scene-text").value = await file.text();
  });
  $("submit-form").addEventListener("submit", async (e) => {
    e.preventDefault();
    $("submit-errors").hidden = true;
    $("submit-button").disabled = true;
    try {
      const r = await api("/v1/jobs", {
        method: "POST",
        headers: { "Content-Type": "application/json" },
        body: $("scene-text").value,
      });
      if (r.ok && r.body && r.body.id) location.hash = `#/jobs/${r.body.id}`;
      else showSubmitErrors(r.body, r.status);
    } catch (err) {
      showSubmitErrors(null, String(err));
    } finally {
      $("submit-button").disabled = false;
    }
  });
}

// ---- views ----

function route() {
  viewAbort.abort();
  viewAbort = new AbortController();
  timers.forEach(clearInterval);
  timers = [];
  const hash = location.hash || "#/";
  const job = hash.match(/^#\/jobs\/([0-9a-fA-F-]{36})$/);
  for (const v of ["view-jobs", "view-job", "view-submit"]) $(v).hidden = true;
  if (job) {
    $("view-job").hidden = false;
    showJob(job[1], viewAbort.signal).catch(() => {});
  } else if (hash === "#/submit") {
    $("view-submit").hidden = false;
  } else {
    $("view-jobs").hidden = false;
    showJobs(viewAbort.signal);
  }
}

$("token").value = token;
$("token-form").addEventListener("submit", (e) => {
  e.preventDefault();
  token = $("token").value.trim();
  localStorage.setItem(TOKEN_KEY, token);
  notice("");
  route();
});
setUpSubmit();
window.addEventListener("hashchange", route);
route();
