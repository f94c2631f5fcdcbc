// stageid serve: the page talks to the JSON API of stageid.app.server; no other network.
"use strict";
const $ = (id) => document.getElementById(id);
let current = null; // {source, name, info} of the opened record
let job = null;     // the job being polled

function showError(text) { const e = $("error"); e.textContent = text || ""; e.hidden = !text; }

// this tab's session: kept in the tab's own storage, so two tabs never share their work
const sessionKey = () => sessionStorage.getItem("stageid-session") || "";
const fileLink = (name) => `/api/files/${encodeURIComponent(name)}?session=${encodeURIComponent(sessionKey())}`;

async function api(path, body, raw) {
  const headers = { "X-Stageid-Session": sessionKey() };
  if (body !== undefined && !raw) headers["Content-Type"] = "application/json";
  const opts = body === undefined ? { headers } : { method: "POST", body: raw ? body : JSON.stringify(body), headers };
  const response = await fetch(path, opts);
  const key = response.headers.get("X-Stageid-Session");
  if (key) sessionStorage.setItem("stageid-session", key);
  const data = await response.json().catch(() => ({ error: `stageid: error: server answered ${response.status}` }));
  if (!response.ok || data.error) { showError(data.error); throw new Error(data.error); }
  showError("");
  return data;
}

function fill(select, names, keep) {
  const old = select.value;
  select.innerHTML = "";
  for (const n of names) { const o = document.createElement("option"); o.value = o.textContent = n; select.appendChild(o); }
  if (keep && names.includes(old)) select.value = old;
}

function figures(box, figs) {
  box.innerHTML = "";
  for (const [name, svg] of Object.entries(figs || {})) {
    const div = document.createElement("div"); div.className = "figure"; div.dataset.name = name;
    div.innerHTML = svg; box.appendChild(div);
  }
}

async function refresh() {
  const s = await api("/api/state");
  $("folder").textContent = "records of " + s.folder;
  const records = s.records.map((r) => "folder:" + r).concat(s.uploads.map((u) => "upload:" + u));
  fill($("record"), records, true);
  const sets = Object.keys(s.datasets), times = sets.filter((k) => s.datasets[k].kind === "time");
  const label = (k) => k;
  fill($("estimate-data"), sets.map(label), true);
  fill($("compare-data"), times, true);
  const models = Object.keys(s.models);
  fill($("compare-model"), models, true);
  fill($("opt-controller"), s.model_files.concat(["unknown"]), true); // unknown: the direct prediction-error route
  fill($("export-model"), models, true);
  return s;
}

function splitRecord(value) { const i = value.indexOf(":"); return { source: value.slice(0, i), name: value.slice(i + 1) }; }

function showRecord(info) {
  $("time-settings").hidden = info.kind !== "time";
  $("frd-settings").hidden = info.kind !== "frd";
  if (info.kind === "time") {
    fill($("inputs"), info.columns); fill($("outputs"), info.columns);
    $("record-info").textContent = `${info.n_samples} samples` + (info.dt ? `, dt ${info.dt} s` : ", no time column");
  } else {
    fill($("response"), Object.keys(info.responses));
    $("record-info").textContent = `${Object.keys(info.responses).length} frequency response(s)`;
  }
  $("prepare").disabled = false;
}

async function openRecord() {
  current = splitRecord($("record").value);
  const ts = encodeURIComponent($("ts").value.trim());
  current.info = await api(`/api/inspect?source=${current.source}&name=${encodeURIComponent(current.name)}&ts=${ts}`);
  showRecord(current.info);
}

async function uploadFile() {
  const file = $("upload").files[0];
  if (!file) return;
  const info = await api(`/api/upload?name=${encodeURIComponent(file.name)}&ts=${encodeURIComponent($("ts").value.trim())}`, file, true);
  await refresh();
  $("record").value = "upload:" + info.name;
  current = { source: "upload", name: info.name, info };
  showRecord(info);
}

const chosen = (select) => Array.from(select.selectedOptions).map((o) => o.value);
const number = (id) => ($(id).value.trim() === "" ? null : Number($(id).value));

async function prepare() {
  const settings = current.info.kind === "time"
    ? { inputs: chosen($("inputs")), outputs: chosen($("outputs")), start: number("start"), stop: number("stop"),
        detrend: $("detrend").value, ts: $("ts").value.trim(), decimate: number("decimate") }
    : { response: $("response").value, fmin: number("band-fmin"), fmax: number("band-fmax") };
  const d = await api("/api/prepare", { source: current.source, name: current.name, settings });
  figures($("data-figures"), d.figures);
  $("data-python").textContent = d.python;
  $("record-info").textContent = `data set ${d.name} made`;
  const a = $("data-download"); a.href = fileLink(d.file); a.download = d.file; a.textContent = "download " + d.file; a.hidden = false;
  await refresh();
  $("estimate-data").value = d.name;
}

function estimateOptions(method) {
  if (method === "frf") return { method: $("opt-frf-method").value, segment: $("opt-segment").value, periods: $("opt-periods").value };
  if (method === "statespace") return { order: $("opt-ss-order").value, horizon: $("opt-horizon").value };
  if (method === "frd") return { order: $("opt-order").value, dt: $("opt-dt").value, continuous: $("opt-continuous").checked,
    fmin: $("opt-fmin").value, fmax: $("opt-fmax").value, delay: $("opt-delay").value };
  if (method === "closedloop") {
    return { controller: $("opt-controller").value, band: $("opt-band").value, order: $("opt-cl-order").value };
  }
  return { model: $("opt-hyst").value };
}

function follow(state, done) {
  job = state; // the one the Cancel button stops
  $("job").hidden = false;
  $("job-title").textContent = state.title;
  const tick = async () => {
    const s = await api(`/api/jobs/${state.id}`).catch(() => null);
    if (!s) return;
    if (job.id === state.id) {
      $("job-elapsed").textContent = `${s.elapsed.toFixed(1)} s`;
      $("job-status").textContent = s.status;
      $("job-progress").hidden = s.status !== "running";
      $("job-cancel").disabled = s.status !== "running";
    }
    if (s.status === "running") { setTimeout(tick, 250); return; }
    if (s.status === "done") { await done(s); await refresh(); } else { showError(s.error); }
  };
  tick();
}

async function runEstimate() {
  const method = $("estimate-method").value;
  const data = method === "closedloop" ? chosen($("estimate-data")).join(",") : $("estimate-data").value;
  const s = await api("/api/estimate", { method, data, options: estimateOptions(method) });
  $("estimate-cli").textContent = s.cli; $("estimate-python").textContent = s.python;
  follow(s, (done) => {
    figures($("estimate-figures"), done.result.figures);
    const m = done.result.model || done.result.dataset;
    $("estimate-summary").textContent = m ? `${m.name}: ${m.summary || m.kind}` : "";
  });
}

async function runOrder() {
  const s = await api("/api/order", { data: $("estimate-data").value, options: { horizon: $("opt-horizon").value } });
  $("estimate-cli").textContent = ""; $("estimate-python").textContent = s.python;
  follow(s, (done) => figures($("order-figures"), done.result.figures));
}

function validationTable(summary) {
  const rows = ["<tr><th>output</th><th>fit %</th><th>NRMSE</th><th>residual white</th><th>independent of inputs</th></tr>"];
  for (const [name, o] of Object.entries(summary.outputs || {})) {
    const fit = typeof o.fit_percent === "number" ? o.fit_percent.toFixed(1) : o.fit_percent;
    const nrmse = typeof o.nrmse === "number" ? o.nrmse.toPrecision(3) : o.nrmse;
    rows.push(`<tr><td>${name}</td><td class="fit">${fit}</td><td>${nrmse}</td><td>${o.whiteness.pass}</td><td>${o.independence.pass}</td></tr>`);
  }
  return rows.join("");
}

async function runCompare() {
  const s = await api("/api/compare", { model: $("compare-model").value, data: $("compare-data").value });
  $("compare-cli").textContent = s.cli; $("compare-python").textContent = s.python;
  follow(s, (done) => { $("compare-table").innerHTML = validationTable(done.result.validation); figures($("compare-figures"), done.result.figures); });
}

async function runExport() {
  const s = await api("/api/export", { model: $("export-model").value, format: $("export-format").value, options: { prefix: $("export-prefix").value } });
  $("export-cli").textContent = s.cli || "(the model file the estimate's command wrote)"; $("export-python").textContent = s.python;
  $("download").hidden = true;
  follow(s, (done) => { const a = $("download"); a.href = fileLink(done.result.file); a.download = done.result.file; a.textContent = "download " + done.result.file; a.hidden = false; });
}

function showBoard(name) {
  for (const b of document.querySelectorAll(".board")) b.hidden = b.id !== "board-" + name;
  for (const t of document.querySelectorAll(".tab")) t.classList.toggle("active", t.dataset.board === name);
}

function showOptions() {
  $("estimate-data").multiple = $("estimate-method").value === "closedloop"; // one data set per reference
  for (const o of document.querySelectorAll(".options")) o.hidden = o.dataset.for !== $("estimate-method").value;
}

const quiet = (f) => () => f().catch(() => {}); // errors are already shown in the page
window.addEventListener("DOMContentLoaded", () => {
  for (const t of document.querySelectorAll(".tab")) t.addEventListener("click", () => showBoard(t.dataset.board));
  $("inspect").addEventListener("click", quiet(openRecord));
  $("upload").addEventListener("change", quiet(uploadFile));
  $("prepare").addEventListener("click", quiet(prepare));
  $("estimate-method").addEventListener("change", showOptions);
  $("run-estimate").addEventListener("click", quiet(runEstimate));
  $("run-order").addEventListener("click", quiet(runOrder));
  $("run-compare").addEventListener("click", quiet(runCompare));
  $("run-export").addEventListener("click", quiet(runExport));
  $("job-cancel").addEventListener("click", () => job && api(`/api/jobs/${job.id}/cancel`, {}).catch(() => {}));
  refresh().catch(() => {});
});
