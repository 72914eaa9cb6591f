/* RIS planner page: plain DOM + SVG, no framework and no network access beyond this server.
 *
 * Data flow: a plan document (preset, upload, or a GeoJSON import where the server offers one)
 * → the form edits a few key fields → POST /v1/plans/validate (422 field errors shown next to
 * their inputs; a valid answer previews the expanded sites and UE maps, drawn to scale) →
 * POST /v1/plans → progress from GET /v1/jobs/{id}/events (server-sent events, read with fetch
 * so an API key header can be sent; reconnects with backoff) → GET /v1/jobs/{id}: plan.json's
 * by_count, points and heatmap drawn on the map and in the charts.
 */
(function () {
  "use strict";

  const SVG_NS = "http://www.w3.org/2000/svg";
  const IMPORT_PATH = /(geojson|import)/i; // a POST path of the server that turns a GeoJSON site into a plan document
  const COUNT_COLOURS = ["#1f5fa8", "#c0392b", "#1e7b34", "#7b3fa0", "#b35900", "#00707a", "#8a5a00", "#444444"];
  const VIRIDIS = ["#440154", "#472d7b", "#3b528b", "#2c728e", "#21918c", "#28ae80", "#5ec962", "#addc30", "#fde725"];
  const BLIND_COLOUR = "#d7301f";
  const HEALTH_BACKOFF_MS = [2000, 4000, 8000, 15000, 30000];
  const STREAM_BACKOFF_MAX_MS = 30000;
  const JOB_LIST_LIMIT = 15;
  const LABEL_FETCH_LIMIT = 10;
  const METRIC_LABEL = { rx: "PEB_R", tx: "PEB_T", max: "max(PEB_T, PEB_R)" };

  const state = {
    presets: [],
    doc: null,
    docName: "",
    preview: null,
    job: null,
    plan: null,
    count: null,
    layoutIdx: 0,
    selected: null, // index into plan.points
    follower: null, // AbortController of the progress stream
    serverUp: null,
    healthTimer: null,
    healthTry: 0,
    apiKey: sessionStorage.getItem("rp.apiKey") || "",
    importPath: null,
    wavefrontSupported: true,
    view: null, // map transform
    groups: null, // RX points grouped by x–y position
  };

  const $ = (id) => document.getElementById(id);

  // ---------------------------------------------------------------- DOM helpers
  function h(tag, attrs, ...children) {
    const el = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined || v === false) continue;
      if (k === "text") el.textContent = v;
      else if (k.startsWith("on")) el.addEventListener(k.slice(2), v);
      else el.setAttribute(k, v === true ? "" : String(v));
    }
    for (const c of children.flat()) {
      if (c === null || c === undefined) continue;
      el.append(c instanceof Node ? c : document.createTextNode(String(c)));
    }
    return el;
  }
  function s(tag, attrs, ...children) {
    const el = document.createElementNS(SVG_NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined) continue;
      el.setAttribute(k, String(v));
    }
    for (const c of children.flat()) {
      if (c === null || c === undefined) continue;
      el.append(c instanceof Node ? c : document.createTextNode(String(c)));
    }
    return el;
  }
  const clear = (el) => { while (el.firstChild) el.removeChild(el.firstChild); return el; };
  const sleep = (ms, signal) => new Promise((resolve, reject) => {
    const t = setTimeout(resolve, ms);
    if (signal) signal.addEventListener("abort", () => { clearTimeout(t); reject(new DOMException("aborted", "AbortError")); });
  });

  function fmtNum(v, digits = 3) {
    if (v === null || v === undefined) return "—";
    if (!Number.isFinite(v)) return "∞";
    if (v === 0) return "0";
    const a = Math.abs(v);
    if (a >= 1e4 || a < 1e-3) return v.toExponential(digits - 1);
    return Number(v.toPrecision(digits)).toString();
  }
  const fmtM = (v) => (v === null || v === undefined ? "blind (∞)" : `${fmtNum(v)} m`);
  const deg = (rad) => (rad * 180) / Math.PI;
  function fmtTime(iso) {
    if (!iso) return "—";
    const d = new Date(iso);
    return Number.isNaN(d.getTime()) ? iso : d.toLocaleString();
  }

  // ---------------------------------------------------------------- server access
  class ApiError extends Error {
    constructor(status, body) {
      super(friendlyMessage(status, body));
      this.status = status;
      this.body = body;
    }
  }

  function friendlyMessage(status, body) {
    if (status === 0) {
      return `The server at ${location.origin} does not answer. Check that it is running (ris-planner serve) and reachable.`;
    }
    let msg = body && typeof body.message === "string" ? body.message : "";
    if (/Traceback|File "/.test(msg)) msg = ""; // never show a traceback
    if (msg.length > 400) msg = msg.slice(0, 400) + "…";
    if (status >= 500) {
      return `The server had an internal problem (HTTP ${status})${msg ? ": " + msg : ""}. Try again; the server log has the details.`;
    }
    if (status === 401) return "The server needs an API key: enter it under “Server API key” and try again.";
    return msg || `The request failed (HTTP ${status}).`;
  }

  function headers(extra) {
    const out = Object.assign({}, extra || {});
    if (state.apiKey) out["X-API-Key"] = state.apiKey;
    return out;
  }

  async function api(path, opts = {}) {
    const init = { method: opts.method || "GET", headers: headers(opts.headers), signal: opts.signal };
    if (opts.json !== undefined) {
      init.headers["Content-Type"] = "application/json";
      init.body = JSON.stringify(opts.json);
    } else if (opts.body !== undefined) {
      init.headers["Content-Type"] = opts.contentType || "application/octet-stream";
      init.body = opts.body;
    }
    let resp;
    try {
      resp = await fetch(path, init);
    } catch (err) {
      if (err && err.name === "AbortError") throw err;
      serverDown();
      throw new ApiError(0, null);
    }
    serverUp();
    let body = null;
    if ((resp.headers.get("content-type") || "").includes("json")) {
      try { body = await resp.json(); } catch (_) { body = null; }
    }
    if (!resp.ok) throw new ApiError(resp.status, body);
    return body;
  }

  function showBanner(msg) {
    $("banner-text").textContent = msg;
    $("banner").hidden = false;
  }
  function hideBanner() { $("banner").hidden = true; }

  function serverDown() {
    if (state.serverUp === false) return;
    state.serverUp = false;
    const st = $("server-status");
    st.textContent = "Server unreachable";
    st.classList.add("down");
    showBanner(friendlyMessage(0, null) + " Retrying automatically.");
    scheduleHealth();
  }
  function serverUp() {
    if (state.serverUp === true) return;
    const wasDown = state.serverUp === false;
    state.serverUp = true;
    state.healthTry = 0;
    $("server-status").classList.remove("down");
    if (wasDown) {
      hideBanner();
      checkHealth();
      refreshJobs();
    }
  }
  function scheduleHealth() {
    clearTimeout(state.healthTimer);
    const wait = HEALTH_BACKOFF_MS[Math.min(state.healthTry, HEALTH_BACKOFF_MS.length - 1)];
    state.healthTry += 1;
    state.healthTimer = setTimeout(checkHealth, wait);
  }
  async function checkHealth() {
    try {
      const hz = await api("/healthz");
      const st = $("server-status");
      st.textContent = `Server ${hz.status} · v${hz.version} · ${hz.running}/${hz.workers} workers busy`;
      st.classList.toggle("down", hz.status !== "ok");
    } catch (err) {
      if (err.status && err.status === 503) {
        $("server-status").textContent = "Server up, but its job database does not answer";
        $("server-status").classList.add("down");
      }
      if (state.serverUp === false) scheduleHealth();
    }
  }

  // ---------------------------------------------------------------- document and form
  const FIELD_IDS = ["f-ris_count", "f-objective-kind", "f-objective-metric", "f-objective-level",
    "f-ris-rows", "f-ris-cols", "f-power", "f-wavefront"];
  const LEVEL_FIELD = { coverage: "threshold_m", mean_capped: "cap_m", quantile: "q" };
  const LEVEL_LABEL = { coverage: "Coverage threshold [m]", mean_capped: "Cap on the bound [m]", quantile: "Quantile q (0–1)" };

  const get = (obj, path) => path.split(".").reduce((o, k) => (o && typeof o === "object" ? o[k] : undefined), obj);

  function setDocument(doc, name) {
    state.doc = doc;
    state.docName = name;
    state.preview = null;
    const fr = doc && doc.frame;
    const where = fr && Array.isArray(fr.origin)
      ? ` · geographic frame at ${fr.origin.slice(0, 2).map((v) => fmtNum(Number(v), 7)).join(", ")}: drawn in local metres east/north of it`
      : fr ? " · geographic frame: drawn in local metres" : "";
    $("doc-name").textContent = `Document: ${name}` + (doc && doc.description ? ` – ${doc.description}` : "") + where;
    fillForm();
    clearErrors();
  }

  function fillForm() {
    const doc = state.doc || {};
    $("f-ris_count").value = Array.isArray(doc.ris_count) ? doc.ris_count.join(", ") : "";
    const obj = doc.objective || {};
    $("f-objective-kind").value = obj.kind || "coverage";
    $("f-objective-metric").value = obj.metric || "rx";
    updateLevelField();
    const lv = obj[LEVEL_FIELD[$("f-objective-kind").value]];
    $("f-objective-level").value = lv === undefined || lv === null ? "" : String(lv);
    const ris = doc.ris || {};
    $("f-ris-rows").value = ris.rows === undefined ? "10" : String(ris.rows);
    $("f-ris-cols").value = ris.cols === undefined ? "10" : String(ris.cols);
    const sys = doc.system || {};
    $("f-power").value = sys.tx_power_dbm === undefined ? "30" : String(sys.tx_power_dbm);
    $("f-wavefront").value = sys.wavefront || "planar";
  }

  function updateLevelField() {
    const kind = $("f-objective-kind").value;
    $("label-objective-level").textContent = LEVEL_LABEL[kind] || "Level";
    $("f-objective-level").dataset.path = `objective.${LEVEL_FIELD[kind] || "threshold_m"}`;
  }

  function parseNumber(text) {
    const t = text.trim();
    if (t === "") return undefined;
    const v = Number(t);
    return Number.isFinite(v) ? v : t; // the server names what is wrong with a non-number
  }

  /** The current document with the form's values written into it (a copy). */
  function documentFromForm() {
    const doc = JSON.parse(JSON.stringify(state.doc || {}));
    const counts = $("f-ris_count").value.split(/[\s,;]+/).filter(Boolean)
      .map((t) => (/^[-+]?\d+$/.test(t) ? Number(t) : t));
    doc.ris_count = counts;
    const kind = $("f-objective-kind").value;
    const obj = Object.assign({}, doc.objective || {});
    obj.kind = kind;
    obj.metric = $("f-objective-metric").value;
    for (const k of Object.values(LEVEL_FIELD)) delete obj[k];
    const level = parseNumber($("f-objective-level").value);
    if (level !== undefined) obj[LEVEL_FIELD[kind]] = level;
    doc.objective = obj;
    doc.ris = Object.assign({}, doc.ris || {});
    for (const [id, key] of [["f-ris-rows", "rows"], ["f-ris-cols", "cols"]]) {
      const v = parseNumber($(id).value);
      if (v === undefined) delete doc.ris[key]; else doc.ris[key] = v;
    }
    doc.system = Object.assign({}, doc.system || {});
    const p = parseNumber($("f-power").value);
    if (p === undefined) delete doc.system.tx_power_dbm; else doc.system.tx_power_dbm = p;
    const wf = $("f-wavefront").value;
    if (wf !== "planar" || doc.system.wavefront !== undefined) doc.system.wavefront = wf;
    return doc;
  }

  function clearErrors() {
    for (const id of FIELD_IDS) {
      $(id).removeAttribute("aria-invalid");
      $(`err-${id}`).textContent = "";
    }
    clear($("other-errors"));
    $("validation-status").textContent = "";
  }

  function inputForField(field) {
    let best = null;
    let bestLen = -1;
    for (const id of FIELD_IDS) {
      const el = $(id);
      const paths = [el.dataset.path, ...(el.dataset.alias ? [el.dataset.alias] : [])];
      for (const p of paths) {
        if ((field === p || field.startsWith(p + ".")) && p.length > bestLen) {
          best = el;
          bestLen = p.length;
        }
      }
    }
    return best;
  }

  /** Show a 422/413 answer: each field problem next to its input, the rest in a list. */
  function showErrors(err) {
    clearErrors();
    const body = err.body || {};
    const fields = Array.isArray(body.fields) ? body.fields : [];
    const rest = [];
    for (const f of fields) {
      const el = inputForField(String(f.field || ""));
      if (el) {
        el.setAttribute("aria-invalid", "true");
        const box = $(`err-${el.id}`);
        box.textContent = (box.textContent ? box.textContent + " " : "") + `${f.field}: ${f.message}`;
      } else {
        rest.push(`${f.field}: ${f.message}`);
      }
    }
    if (!fields.length) {
      // engine checks without a field path: place them by the path their message starts with
      const msg = err.message;
      const el = inputForField((msg.match(/^[A-Za-z_.0-9]+/) || [""])[0]);
      if (el && err.status === 422) {
        el.setAttribute("aria-invalid", "true");
        $(`err-${el.id}`).textContent = msg;
      } else {
        rest.push(msg);
      }
    }
    if (rest.length) {
      const box = $("other-errors");
      box.append(h("p", { text: err.status === 413 ? "Too large for this server:" : "Problems in the document:" }));
      box.append(h("ul", {}, rest.map((t) => h("li", { text: t }))));
    }
    const first = document.querySelector('[aria-invalid="true"]');
    if (first) first.focus();
  }

  async function validate() {
    if (!state.doc) { $("validation-status").textContent = "Load a preset or upload a document first."; return null; }
    const doc = documentFromForm();
    clearErrors();
    $("validation-status").textContent = "Validating…";
    try {
      const preview = await api("/v1/plans/validate", { method: "POST", json: doc });
      state.preview = preview;
      const per = Object.entries(preview.layouts).map(([c, n]) => `${c} RIS: ${n} layouts (${preview.methods[c]})`).join("; ");
      $("validation-status").textContent =
        `Valid: ${preview.sites} candidate sites, ${preview.pairs} TX–RX pairs, ${preview.rx_points} RX points. ${per}.`;
      if (!state.plan) drawAll();
      return doc;
    } catch (err) {
      $("validation-status").textContent = "";
      if (err.status === 422 || err.status === 413) showErrors(err);
      else showBanner(err.message);
      return null;
    }
  }

  async function submit(ev) {
    ev.preventDefault();
    if (!state.doc) { $("validation-status").textContent = "Load a preset or upload a document first."; return; }
    $("submit").disabled = true;
    try {
      // the dry run first: what the job would fail on at its start is shown at the fields now
      const doc = await validate();
      if (!doc) return;
      const job = await api("/v1/plans", { method: "POST", json: doc });
      rememberLabel(job.id, describeRequest(doc, state.docName));
      state.plan = null;
      state.selected = null;
      state.count = null;
      $("results").hidden = true;
      $("count-picker").hidden = true;
      drawAll();
      showJob(job);
      follow(job.id);
      refreshJobs();
    } catch (err) {
      if (err.status === 422 || err.status === 413) showErrors(err);
      else showBanner(err.message);
    } finally {
      $("submit").disabled = false;
    }
  }

  async function loadPresets() {
    try {
      const body = await api("/v1/presets");
      state.presets = body.plans || [];
      const sel = clear($("preset"));
      for (const p of state.presets) sel.append(h("option", { value: p.name, text: p.name }));
      if (!state.presets.length) sel.append(h("option", { value: "", text: "(none shipped)" }));
    } catch (err) {
      clear($("preset")).append(h("option", { value: "", text: "(unavailable)" }));
      if (err.status !== 0) showBanner(err.message);
    }
  }

  function loadPreset() {
    const name = $("preset").value;
    const p = state.presets.find((x) => x.name === name);
    if (!p) return;
    state.plan = null;
    state.job = null;
    $("results").hidden = true;
    setDocument(JSON.parse(JSON.stringify(p.document)), `preset ${name}`);
    drawAll();
    validate();
  }

  function readFile(input, errId) {
    return new Promise((resolve) => {
      const file = input.files && input.files[0];
      $(errId).textContent = "";
      if (!file) { resolve(null); return; }
      const reader = new FileReader();
      reader.onload = () => {
        try {
          resolve({ name: file.name, json: JSON.parse(String(reader.result)) });
        } catch (e) {
          $(errId).textContent = `${file.name} is not valid JSON (${e.message}).`;
          resolve(null);
        }
      };
      reader.onerror = () => { $(errId).textContent = `${file.name} could not be read.`; resolve(null); };
      reader.readAsText(file);
    });
  }

  async function uploadDocument() {
    const got = await readFile($("upload"), "err-upload");
    if (!got) return;
    if (!got.json || typeof got.json !== "object" || Array.isArray(got.json)) {
      $("err-upload").textContent = `${got.name}: a plan document is a JSON object.`;
      return;
    }
    state.plan = null;
    state.job = null;
    $("results").hidden = true;
    setDocument(got.json, got.name);
    drawAll();
    validate();
  }

  /** Site import (POST /v1/import, shown when the server's OpenAPI lists it): the file's raw
   * bytes with its format; the answer's plan document goes into the editor, its report below. */
  const IMPORT_FORMATS = { geojson: "geojson", json: "geojson", osm: "osm", xml: "osm", dxf: "dxf" };
  const IMPORT_MEDIA = { geojson: "application/geo+json", osm: "application/xml", dxf: "application/octet-stream" };

  function describeImport(report) {
    if (!report) return "";
    const parts = [];
    for (const [k, label] of [["buildings", "buildings"], ["prisms", "prisms"], ["roads", "roads"], ["areas", "density areas"],
      ["candidates", "candidate sites"], ["walls", "walls"], ["skipped", "features skipped"]]) {
      if (report[k]) parts.push(`${report[k]} ${label}`);
    }
    if (Array.isArray(report.default_height) && report.default_height.length) {
      parts.push(`${report.default_height.length} building(s) given the default height`);
    }
    const notes = (report.notes || []).join(" ");
    return `Imported (${report.format}): ${parts.join(", ") || "nothing usable"}.` + (notes ? ` ${notes}` : "") +
      ((report.defaults_applied || []).length ? ` Defaults: ${report.defaults_applied.join("; ")}.` : "");
  }

  async function importGeojson() {
    const input = $("upload-geojson");
    const file = input.files && input.files[0];
    $("err-upload-geojson").textContent = "";
    $("import-report").textContent = "";
    input.removeAttribute("aria-invalid");
    if (!file || !state.importPath) return;
    const ext = ((file.name.match(/\.([A-Za-z0-9]+)$/) || [])[1] || "").toLowerCase();
    const fmt = IMPORT_FORMATS[ext] || "geojson";
    const params = new URLSearchParams({ format: fmt });
    if (fmt === "dxf") {
      for (const spec of $("import-layers").value.split(/[\s,;]+/).filter(Boolean)) params.append("layer", spec);
    }
    try {
      const bytes = await file.arrayBuffer();
      const body = await api(`${state.importPath}?${params}`, { method: "POST", body: bytes, contentType: IMPORT_MEDIA[fmt] });
      const doc = body && body.document ? body.document : body;
      if (!doc || typeof doc !== "object") throw new ApiError(422, { message: "the import answered no plan document" });
      state.plan = null;
      state.job = null;
      $("results").hidden = true;
      setDocument(doc, `${file.name} (imported)`);
      $("import-report").textContent = describeImport(body.report);
      drawAll();
      validate();
    } catch (err) {
      if (err && err.name === "AbortError") return;
      input.setAttribute("aria-invalid", "true");
      const fields = err.body && Array.isArray(err.body.fields) ? err.body.fields : [];
      const named = fields.filter((f) => f.field && f.field !== "(document)");
      // a feature's message names it by index, id and name: clearer than its path features.N
      const said = (f) => (f.field.startsWith("features.") ? f.message : `${f.field}: ${f.message}`);
      $("err-upload-geojson").textContent = `${file.name}: ` + (named.length
        ? named.map(said).join("; ")
        : err.message);
    }
  }

  async function inspectServer() {
    try {
      const spec = await api("/openapi.json");
      const paths = spec.paths || {};
      state.importPath = Object.keys(paths).find((p) => IMPORT_PATH.test(p) && paths[p].post) || null;
      $("geojson-box").hidden = !state.importPath;
      const sysSchema = ((spec.components || {}).schemas || {}).SystemParams;
      state.wavefrontSupported = !sysSchema || !sysSchema.properties || "wavefront" in sysSchema.properties;
      $("hint-wavefront").textContent = state.wavefrontSupported ? "" : "This server has no wavefront option yet (planar only).";
    } catch (_) {
      /* the page works without it */
    }
  }

  // ---------------------------------------------------------------- jobs and progress
  function showJob(job) {
    state.job = job;
    // 100 % only once the job has succeeded: a plan reports 1.0 before it writes its results
    const raw = Math.round((job.progress || 0) * 100);
    const pct = job.status === "succeeded" ? 100 : Math.min(raw, 99);
    $("progress").value = pct;
    $("progress-text").textContent = `${pct} %`;
    let text = `Job ${job.id.slice(0, 8)}: ${job.status}`;
    if (job.status === "running" && raw >= 100) text += " – writing the results";
    else if (job.message && job.status !== "failed") text += ` – ${job.message}`;
    if (job.status === "failed" && job.error) text += ` – ${job.error}`;
    $("job-status").textContent = text;
    $("cancel").disabled = !(job.status === "queued" || job.status === "running");
  }

  function stopFollowing() {
    if (state.follower) state.follower.abort();
    state.follower = null;
  }

  /** Follow a job's server-sent events until it ends; reconnect with backoff on errors. */
  async function follow(jobId) {
    stopFollowing();
    const ctl = new AbortController();
    state.follower = ctl;
    let backoff = 1000;
    let ended = false;
    let lastStatus = null;
    while (!ended && !ctl.signal.aborted) {
      try {
        const resp = await fetch(`/v1/jobs/${jobId}/events`, { headers: headers(), signal: ctl.signal });
        serverUp();
        if (!resp.ok) {
          let body = null;
          try { body = await resp.json(); } catch (_) { body = null; }
          throw new ApiError(resp.status, body);
        }
        const reader = resp.body.getReader();
        const decoder = new TextDecoder();
        let buf = "";
        for (;;) {
          const { value, done } = await reader.read();
          if (done) break;
          buf += decoder.decode(value, { stream: true });
          let cut;
          while ((cut = buf.indexOf("\n\n")) >= 0) {
            const block = buf.slice(0, cut);
            buf = buf.slice(cut + 2);
            const ev = parseEvent(block);
            if (ev.retry) backoff = ev.retry;
            if (!ev.data) continue;
            const summary = JSON.parse(ev.data);
            if (state.job && state.job.id === jobId) showJob(Object.assign({}, state.job, summary));
            if (summary.status !== lastStatus) {
              if (lastStatus !== null) refreshJobs(); // the list changes with the status only
              lastStatus = summary.status;
            }
            if (ev.event === "end") ended = true;
          }
        }
        backoff = 1000;
      } catch (err) {
        if (ctl.signal.aborted || (err && err.name === "AbortError")) return;
        if (err instanceof ApiError && err.status && err.status !== 0 && err.status < 500) {
          $("job-status").textContent = err.message;
          return;
        }
        if (!(err instanceof ApiError)) serverDown();
        $("job-status").textContent = `Lost the connection to the server; retrying in ${Math.round(backoff / 1000)} s…`;
        try { await sleep(backoff, ctl.signal); } catch (_) { return; }
        backoff = Math.min(backoff * 2, STREAM_BACKOFF_MAX_MS);
      }
    }
    if (ended && !ctl.signal.aborted) {
      state.follower = null;
      await openJob(jobId, false);
      refreshJobs();
    }
  }

  function parseEvent(block) {
    const out = { event: "message", data: "", retry: 0 };
    const data = [];
    for (const line of block.split("\n")) {
      if (!line || line.startsWith(":")) continue;
      const k = line.indexOf(":");
      const field = k < 0 ? line : line.slice(0, k);
      let value = k < 0 ? "" : line.slice(k + 1);
      if (value.startsWith(" ")) value = value.slice(1);
      if (field === "event") out.event = value;
      else if (field === "data") data.push(value);
      else if (field === "retry" && /^\d+$/.test(value)) out.retry = Number(value);
    }
    out.data = data.join("\n");
    return out;
  }

  async function cancelJob() {
    if (!state.job) return;
    $("cancel").disabled = true;
    try {
      const job = await api(`/v1/jobs/${state.job.id}/cancel`, { method: "POST" });
      showJob(job);
      refreshJobs();
    } catch (err) {
      if (err.status === 409) $("job-status").textContent = err.message;
      else showBanner(err.message);
    }
  }

  /** Open a job: its document into the form, its progress followed or its results drawn. */
  async function openJob(jobId, fromList) {
    let view;
    try {
      view = await api(`/v1/jobs/${jobId}`);
    } catch (err) {
      showBanner(err.message);
      return;
    }
    if (fromList) stopFollowing();
    showJob(view);
    if (view.kind !== "plan") {
      $("job-status").textContent += " (not a plan job: nothing to draw)";
      return;
    }
    rememberLabel(view.id, describeRequest(view.request, ""));
    if (fromList || !state.doc) {
      setDocument(view.request, `job ${view.id.slice(0, 8)}`);
    }
    if (view.status === "succeeded" && view.result) {
      state.plan = view.result;
      const counts = state.plan.by_count.map((b) => String(b.ris_count));
      state.count = counts[counts.length - 1];
      state.layoutIdx = 0;
      state.selected = null;
      if (fromList || !state.preview) {
        try { state.preview = await api("/v1/plans/validate", { method: "POST", json: view.request }); } catch (_) { state.preview = null; }
      }
      renderResults();
      drawAll();
    } else {
      state.plan = null;
      $("results").hidden = true;
      drawAll();
      if (view.status === "queued" || view.status === "running") follow(view.id);
    }
  }

  function describeRequest(doc, name) {
    if (!doc) return name || "plan";
    const counts = Array.isArray(doc.ris_count) ? doc.ris_count.join("/") : "?";
    const obj = doc.objective ? doc.objective.kind : "?";
    const head = doc.description ? doc.description.slice(0, 70) + (doc.description.length > 70 ? "…" : "") : (name || "plan document");
    return `${head} · ${counts} RIS · ${obj}`;
  }
  function labels() {
    try { return JSON.parse(localStorage.getItem("rp.jobLabels") || "{}"); } catch (_) { return {}; }
  }
  function rememberLabel(id, label) {
    const all = labels();
    all[id] = label;
    const keys = Object.keys(all);
    if (keys.length > 500) for (const k of keys.slice(0, keys.length - 500)) delete all[k];
    try { localStorage.setItem("rp.jobLabels", JSON.stringify(all)); } catch (_) { /* storage full */ }
  }

  async function refreshJobs() {
    const body = $("jobs-body");
    let page;
    try {
      page = await api(`/v1/jobs?limit=${JOB_LIST_LIMIT}`);
    } catch (err) {
      clear(body).append(h("tr", {}, h("td", { colspan: 5, text: err.message })));
      return;
    }
    const known = labels();
    clear(body);
    if (!page.items.length) body.append(h("tr", {}, h("td", { colspan: 5, text: "No jobs yet." })));
    const missing = [];
    for (const j of page.items) {
      const what = known[j.id] || (j.kind === "plan" ? "plan job" : `${j.kind} job`);
      if (!known[j.id]) missing.push(j.id);
      const current = state.job && state.job.id === j.id;
      body.append(h("tr", { class: current ? "current" : null, "data-job": j.id },
        h("td", {}, h("span", { class: `status status-${j.status}`, text: j.status })),
        h("td", { text: fmtTime(j.created_at) }),
        h("td", { class: "what", text: what + (j.error ? ` – ${j.error}` : "") }),
        h("td", { text: `${Math.round(j.progress * 100)} %` }),
        h("td", {}, h("button", {
          type: "button", class: "secondary small", "aria-label": `Open job ${j.id.slice(0, 8)}`,
          onclick: () => openJob(j.id, true),
        }, "Open"))));
    }
    // what a job is about, for jobs submitted elsewhere: read once, then remembered
    for (const id of missing.slice(0, LABEL_FETCH_LIMIT)) {
      try {
        const view = await api(`/v1/jobs/${id}`);
        const label = view.kind === "plan" ? describeRequest(view.request, "") : `${view.kind} job`;
        rememberLabel(id, label);
        const cell = body.querySelector(`tr[data-job="${id}"] td.what`);
        if (cell) cell.textContent = label + (view.error ? ` – ${view.error}` : "");
      } catch (_) { break; }
    }
  }

  // ---------------------------------------------------------------- results panel
  function countEntry(count) {
    return state.plan ? state.plan.by_count.find((b) => String(b.ris_count) === String(count)) : null;
  }
  const colourOf = (count) => {
    const idx = state.plan ? state.plan.by_count.findIndex((b) => String(b.ris_count) === String(count)) : 0;
    return COUNT_COLOURS[Math.max(idx, 0) % COUNT_COLOURS.length];
  };
  function fmtObjective(v) {
    if (v === null || v === undefined) return "—";
    const kind = state.plan.objective.kind;
    return kind === "coverage" ? `${(100 * v).toFixed(1)} %` : `${fmtNum(v)} m`;
  }

  function renderResults() {
    const plan = state.plan;
    $("results").hidden = false;
    const metric = METRIC_LABEL[plan.objective.metric] || plan.objective.metric;
    const better = plan.objective_better === "higher" ? "higher is better" : "lower is better";
    $("results-note").textContent =
      `Objective: ${plan.objective.kind} of ${metric} (${better}); ${plan.pairs} TX–RX pairs scored. ` +
      (plan.heatmap ? `Heatmap: ${plan.heatmap.tx}; contour at ${plan.heatmap.threshold_label}.` : "This job has no heatmap data (older version).");
    // count picker (rebuilt only for another plan, so arrow keys keep their focus in it)
    const opts = $("count-options");
    if (opts.dataset.plan !== state.job.id) {
      clear(opts);
      opts.dataset.plan = state.job.id;
      for (const b of plan.by_count) {
        const id = `count-${b.ris_count}`;
        const input = h("input", { type: "radio", name: "count", id, value: String(b.ris_count) });
        input.addEventListener("change", () => {
          state.count = input.value;
          state.layoutIdx = 0;
          renderResults();
          drawAll();
        });
        opts.append(h("label", { class: "inline", for: id }, input, `${b.ris_count} RIS`));
      }
    }
    for (const input of opts.querySelectorAll("input")) input.checked = input.value === state.count;
    $("count-picker").hidden = false;
    // table per count
    const table = clear($("count-table"));
    table.append(h("caption", { class: "sr-only", text: "Best layout per RIS count" }));
    table.append(h("thead", {}, h("tr", {}, ["RIS", "Objective", "Median", "90 %", "Blind", "Gain vs previous", "Gain per added RIS", "Best sites", "Search"]
      .map((t) => h("th", { scope: "col", text: t })))));
    const tb = h("tbody");
    let prevCount = null;
    for (const b of plan.by_count) {
      const gainPer = b.marginal_gain === null || prevCount === null ? null : b.marginal_gain / (b.ris_count - prevCount);
      tb.append(h("tr", { class: String(b.ris_count) === state.count ? "current" : null },
        h("th", { scope: "row", text: `${b.ris_count}` }),
        h("td", { text: fmtObjective(b.objective) }),
        h("td", { text: fmtM(b.quantiles_m["0.5"]) }),
        h("td", { text: fmtM(b.quantiles_m["0.9"]) }),
        h("td", { text: `${(100 * b.blind_fraction).toFixed(1)} %` }),
        h("td", { text: fmtGain(b.marginal_gain) }),
        h("td", { text: fmtGain(gainPer) }),
        h("td", { text: b.sites.join(", ") }),
        h("td", { text: `${b.method}, ${b.layouts_evaluated}/${b.layouts_total}` })));
      prevCount = b.ris_count;
    }
    table.append(tb);
    drawCdf();
    drawGain();
    // top layouts of the shown count
    const list = clear($("top-layouts"));
    const entry = countEntry(state.count);
    (entry ? entry.top_layouts : []).forEach((lay, i) => {
      const btn = h("button", {
        type: "button", class: "secondary small", id: `layout-${i}`, "aria-pressed": String(i === state.layoutIdx),
        onclick: () => { state.layoutIdx = i; renderResults(); drawAll(); $(`layout-${i}`).focus(); },
      }, i === state.layoutIdx ? "Shown" : "Show");
      list.append(h("li", {}, `sites ${lay.sites.join(", ")} – objective ${fmtObjective(lay.objective)} `, btn));
    });
    renderDownloads();
  }

  function fmtGain(g) {
    if (g === null || g === undefined) return "—";
    return state.plan.objective.kind === "coverage" ? `${(100 * g).toFixed(1)} pts` : `${fmtNum(g)} m`;
  }

  /** File type of a job's non-PNG files by name (ris_planner.io.export.GIS_FILES). */
  const FILE_KINDS = { geojson: "geojson", geotiff: "tif", points_csv: "csv" };

  /** Download links: plan.json and every file the job lists (figures, and any other files). */
  function jobFiles(view) {
    const out = [];
    const add = (name, ref, kind) => {
      if (!ref) return;
      const url = typeof ref === "string" ? ref : ref.url || ref.href || ref.path;
      if (!url) return;
      const ext = ((url.split("?")[0].match(/\.([A-Za-z0-9]+)$/) || [])[1] || (name.match(/\.([A-Za-z0-9]+)$/) || [])[1] || kind || "file").toUpperCase();
      out.push({ name: typeof ref === "object" && ref.name ? ref.name : name, url, ext });
    };
    for (const [name, ref] of Object.entries(view.figures || {})) add(name, ref, FILE_KINDS[name] || "png");
    const files = view.files || {};
    if (Array.isArray(files)) files.forEach((f, i) => add(f.name || `file ${i + 1}`, f, null));
    else for (const [name, ref] of Object.entries(files)) add(name, ref, null);
    return out;
  }

  function renderDownloads() {
    const ul = clear($("downloads"));
    const id8 = state.job ? state.job.id.slice(0, 8) : "plan";
    const blob = new Blob([JSON.stringify(state.plan, null, 1)], { type: "application/json" });
    ul.append(h("li", {}, h("a", { href: URL.createObjectURL(blob), download: `plan-${id8}.json` }, "plan.json"), " (the job's result)"));
    for (const f of jobFiles(state.job || {})) {
      const a = h("a", { href: f.url, download: `${f.name}-${id8}.${f.ext.toLowerCase()}` }, `${f.name}`);
      if (state.apiKey) a.addEventListener("click", (ev) => { ev.preventDefault(); downloadWithKey(f.url, a.getAttribute("download")); });
      ul.append(h("li", {}, a, ` (${f.ext})`));
    }
  }

  async function downloadWithKey(url, name) {
    try {
      const resp = await fetch(url, { headers: headers() });
      if (!resp.ok) throw new ApiError(resp.status, null);
      const link = h("a", { href: URL.createObjectURL(await resp.blob()), download: name });
      document.body.append(link);
      link.click();
      link.remove();
    } catch (err) {
      showBanner(err instanceof ApiError ? err.message : friendlyMessage(0, null));
    }
  }

  // ---------------------------------------------------------------- charts
  function niceTicksLog(lo, hi) {
    const out = [];
    for (let e = Math.floor(Math.log10(lo)); e <= Math.ceil(Math.log10(hi)); e++) {
      for (const m of [1, 2, 5]) {
        const v = m * 10 ** e;
        if (v >= lo * 0.999 && v <= hi * 1.001) out.push(v);
      }
    }
    return out;
  }

  function drawCdf() {
    const svg = clear($("cdf"));
    const plan = state.plan;
    const W = svg.clientWidth || 520;
    const H = svg.clientHeight || 260;
    svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
    const m = { l: 46, r: 10, t: 10, b: 36 };
    let lo = Infinity;
    let hi = -Infinity;
    for (const b of plan.by_count) for (const v of b.cdf.bound_m) if (v !== null && v > 0) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    const thr = plan.objective.kind === "coverage" ? plan.objective.threshold_m : null;
    if (thr) { lo = Math.min(lo, thr); hi = Math.max(hi, thr); }
    if (!Number.isFinite(lo)) { svg.append(s("text", { x: 10, y: 20 }, "Every pair is blind: no finite bound.")); return; }
    if (hi <= lo * 1.0001) hi = lo * 1.1;
    const X = (v) => m.l + ((Math.log10(v) - Math.log10(lo)) / (Math.log10(hi) - Math.log10(lo))) * (W - m.l - m.r);
    const Y = (p) => H - m.b - p * (H - m.t - m.b);
    const axes = s("g", { stroke: "#4d5561", "stroke-width": 1 });
    axes.append(s("line", { x1: m.l, y1: Y(0), x2: W - m.r, y2: Y(0) }), s("line", { x1: m.l, y1: Y(0), x2: m.l, y2: Y(1) }));
    svg.append(axes);
    for (const v of niceTicksLog(lo, hi)) {
      svg.append(s("line", { x1: X(v), y1: Y(0), x2: X(v), y2: Y(1), stroke: "#e3e5e8" }));
      svg.append(s("text", { x: X(v), y: H - m.b + 14, "text-anchor": "middle", "font-size": 10, fill: "#333" }, fmtNum(v, 2)));
    }
    for (const p of [0, 0.5, 1]) svg.append(s("text", { x: m.l - 4, y: Y(p) + 3, "text-anchor": "end", "font-size": 10, fill: "#333" }, String(p)));
    const metric = METRIC_LABEL[plan.objective.metric] || "bound";
    svg.append(s("text", { x: (W + m.l) / 2, y: H - 4, "text-anchor": "middle", "font-size": 11, fill: "#1a1a1a" }, `${metric} [m] (log)`));
    svg.append(s("text", { x: 12, y: (H - m.b) / 2, "font-size": 11, fill: "#1a1a1a", transform: `rotate(-90 12 ${(H - m.b) / 2})`, "text-anchor": "middle" }, "Pr(bound ≤ x)"));
    if (thr) svg.append(s("line", { x1: X(thr), y1: Y(0), x2: X(thr), y2: Y(1), stroke: "#1a1a1a", "stroke-dasharray": "4 3" }));
    plan.by_count.forEach((b, k) => {
      const pts = [];
      let prevP = 0;
      b.cdf.bound_m.forEach((v, i) => {
        if (v === null || v <= 0) return;
        const p = b.cdf.probability[i];
        pts.push(`${X(v).toFixed(1)},${Y(prevP).toFixed(1)}`, `${X(v).toFixed(1)},${Y(p).toFixed(1)}`);
        prevP = p;
      });
      if (pts.length) pts.push(`${(W - m.r).toFixed(1)},${Y(prevP).toFixed(1)}`);
      const shown = String(b.ris_count) === state.count;
      svg.append(s("polyline", {
        points: pts.join(" "), fill: "none", stroke: COUNT_COLOURS[k % COUNT_COLOURS.length],
        "stroke-width": shown ? 2.6 : 1.4, "data-count": b.ris_count,
      }));
      svg.append(s("text", { x: m.l + 8, y: m.t + 12 + 13 * k, "font-size": 11, fill: COUNT_COLOURS[k % COUNT_COLOURS.length], "font-weight": shown ? 700 : 400 },
        `${b.ris_count} RIS`));
    });
    svg.setAttribute("aria-label", `CDF of ${metric} for ${plan.by_count.map((b) => b.ris_count).join(", ")} RISs; median ` +
      plan.by_count.map((b) => `${b.ris_count} RIS ${fmtM(b.quantiles_m["0.5"])}`).join(", "));
  }

  function drawGain() {
    const svg = clear($("gain"));
    const plan = state.plan;
    const W = svg.clientWidth || 340;
    const H = svg.clientHeight || 260;
    svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
    const bars = [];
    for (let i = 1; i < plan.by_count.length; i++) {
      const b = plan.by_count[i];
      const prev = plan.by_count[i - 1];
      const g = b.marginal_gain === null ? null : b.marginal_gain / (b.ris_count - prev.ris_count);
      bars.push({ label: `${prev.ris_count}→${b.ris_count}`, g, k: i });
    }
    if (!bars.length) { svg.append(s("text", { x: 10, y: 20, "font-size": 12 }, "One RIS count only: no gain to show.")); return; }
    const m = { l: 50, r: 10, t: 14, b: 36 };
    const vals = bars.map((b) => b.g).filter((g) => g !== null);
    const top = Math.max(0, ...vals) || 1;
    const bottom = Math.min(0, ...vals);
    const Y = (v) => m.t + ((top - v) / (top - bottom || 1)) * (H - m.t - m.b);
    const bw = (W - m.l - m.r) / bars.length;
    svg.append(s("line", { x1: m.l, y1: Y(0), x2: W - m.r, y2: Y(0), stroke: "#4d5561" }));
    const coverage = plan.objective.kind === "coverage";
    bars.forEach((b, i) => {
      const x = m.l + i * bw + bw * 0.2;
      if (b.g !== null) {
        const y0 = Y(Math.max(b.g, 0));
        svg.append(s("rect", { x, y: y0, width: bw * 0.6, height: Math.max(1, Math.abs(Y(b.g) - Y(0))), fill: COUNT_COLOURS[b.k % COUNT_COLOURS.length] }));
      }
      svg.append(s("text", { x: x + bw * 0.3, y: H - m.b + 14, "text-anchor": "middle", "font-size": 11, fill: "#1a1a1a" }, b.label));
      svg.append(s("text", { x: x + bw * 0.3, y: (b.g === null ? Y(0) : Y(Math.max(b.g, 0))) - 3, "text-anchor": "middle", "font-size": 10, fill: "#1a1a1a" },
        b.g === null ? "n/a" : coverage ? `${(100 * b.g).toFixed(1)} pts` : `${fmtNum(b.g)} m`));
    });
    svg.append(s("text", { x: (W + m.l) / 2, y: H - 4, "text-anchor": "middle", "font-size": 11, fill: "#1a1a1a" },
      coverage ? "coverage gain per added RIS" : "objective reduction per added RIS [m]"));
    svg.setAttribute("aria-label", "Marginal gain per added RIS: " + bars.map((b) => `${b.label}: ${fmtGain(b.g)}`).join(", "));
  }

  // ---------------------------------------------------------------- the map
  function viridis(t) {
    const x = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
    const i = Math.min(VIRIDIS.length - 2, Math.floor(x));
    const f = x - i;
    const a = VIRIDIS[i];
    const b = VIRIDIS[i + 1];
    const c = (hex, o) => parseInt(hex.slice(o, o + 2), 16);
    return [1, 3, 5].map((o) => Math.round(c(a, o) + f * (c(b, o) - c(a, o))));
  }

  /** A document in geographic coordinates (its positions are lon/lat or CRS metres). */
  const geographic = () => Boolean(state.doc && state.doc.frame);

  function obstacles() {
    // the validation preview has them in the local metres of the job (a frame converted)
    if (state.preview && Array.isArray(state.preview.obstacles)) return state.preview.obstacles;
    if (geographic()) return [];
    const env = state.doc && state.doc.environment;
    return env && Array.isArray(env.obstacles) ? env.obstacles : [];
  }
  function candidates() {
    if (state.plan && Array.isArray(state.plan.candidates)) return state.plan.candidates;
    if (state.preview) return state.preview.candidates;
    // not validated (yet): the document's explicit candidates (walls expand on the server)
    if (geographic()) return [];
    const own = state.doc && Array.isArray(state.doc.candidates) ? state.doc.candidates : [];
    return own.filter((c) => c && Array.isArray(c.position) && c.position.length === 3)
      .map((c, i) => ({ index: i, position: c.position, orientation: c.orientation || [0, 0, 0], name: c.name }));
  }
  function ueLayers() {
    const pv = state.preview;
    if (pv) {
      const same = state.doc && JSON.stringify(state.doc.tx_map) === JSON.stringify(state.doc.rx_map);
      return same
        ? [{ name: "UE map (TX = RX)", colour: "#1f5fa8", map: pv.rx_map }]
        : [{ name: "TX map", colour: "#1f5fa8", map: pv.tx_map }, { name: "RX map", colour: "#1e7b34", map: pv.rx_map }];
    }
    if (state.plan && state.plan.points) {
      return [{ name: "RX map", colour: "#1e7b34", map: { points: state.plan.points.map((p) => p.position), weights: state.plan.points.map((p) => p.weight), total: state.plan.points.length, stride: 1 } }];
    }
    return [];
  }

  function worldBounds() {
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    const add = (x, y) => { if (Number.isFinite(x) && Number.isFinite(y)) { x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); } };
    for (const layer of ueLayers()) for (const p of layer.map.points) add(p[0], p[1]);
    for (const c of candidates()) add(c.position[0], c.position[1]);
    for (const ob of obstacles()) {
      if (ob.kind === "prism" && Array.isArray(ob.footprint)) for (const v of ob.footprint) add(v[0], v[1]);
      if (ob.kind === "wall" && ob.start && ob.end) { add(ob.start[0], ob.start[1]); add(ob.end[0], ob.end[1]); }
    }
    const hm = state.plan && state.plan.heatmap;
    if (hm) { const g = hm.grid; add(g.x0 - g.cell_m / 2, g.y0 - g.cell_m / 2); add(g.x0 + (g.nx - 0.5) * g.cell_m, g.y0 + (g.ny - 0.5) * g.cell_m); }
    if (!Number.isFinite(x0)) return null;
    const span = Math.max(x1 - x0, y1 - y0, 1);
    const pad = 0.06 * span;
    return { x0: x0 - pad, x1: x1 + pad, y0: y0 - pad, y1: y1 + pad };
  }

  function niceStep(span, target) {
    const raw = span / target;
    const e = 10 ** Math.floor(Math.log10(raw));
    for (const m of [1, 2, 5, 10]) if (m * e >= raw) return m * e;
    return 10 * e;
  }

  function drawAll() {
    drawMap();
    drawLegend();
    renderSites();
    renderPointInfo();
  }

  function drawMap() {
    const svg = clear($("map"));
    const W = svg.clientWidth || 800;
    const Hmax = svg.clientHeight || 560;
    svg.setAttribute("viewBox", `0 0 ${W} ${Hmax}`);
    const b = worldBounds();
    state.view = null;
    if (!b) {
      svg.append(s("text", { x: 20, y: 30, fill: "#4d5561" }, "No site yet: load a preset or upload a plan document."));
      return;
    }
    const k = Math.min((W - 60) / (b.x1 - b.x0), (Hmax - 40) / (b.y1 - b.y0));
    const ox = 50 + ((W - 60) - k * (b.x1 - b.x0)) / 2;
    const oy = 10 + ((Hmax - 40) - k * (b.y1 - b.y0)) / 2;
    const X = (x) => ox + (x - b.x0) * k;
    const Y = (y) => oy + (b.y1 - y) * k;
    state.view = { X, Y, k, b, inv: (px, py) => [b.x0 + (px - ox) / k, b.y1 - (py - oy) / k] };
    // grid and axis labels
    const step = niceStep(Math.max(b.x1 - b.x0, b.y1 - b.y0), 8);
    const grid = s("g", { stroke: "#e6e8eb", "stroke-width": 1 });
    const labelsG = s("g", { fill: "#4d5561", "font-size": 10 });
    for (let x = Math.ceil(b.x0 / step) * step; x <= b.x1; x += step) {
      grid.append(s("line", { x1: X(x), y1: Y(b.y0), x2: X(x), y2: Y(b.y1) }));
      labelsG.append(s("text", { x: X(x), y: Y(b.y0) + 12, "text-anchor": "middle" }, fmtNum(x, 4)));
    }
    for (let y = Math.ceil(b.y0 / step) * step; y <= b.y1; y += step) {
      grid.append(s("line", { x1: X(b.x0), y1: Y(y), x2: X(b.x1), y2: Y(y) }));
      labelsG.append(s("text", { x: X(b.x0) - 4, y: Y(y) + 3, "text-anchor": "end" }, fmtNum(y, 4)));
    }
    svg.append(grid, labelsG);
    // heatmap and contour
    if (state.plan && state.plan.heatmap && state.count) drawHeatmap(svg, X, Y, k);
    // obstacles
    const obsG = s("g", { id: "obstacles" });
    for (const ob of obstacles()) {
      const top = (Number(ob.base_m) || 0) + (Number(ob.height_m) || 0);
      const title = s("title", {}, `${ob.kind}${ob.name ? " " + ob.name : ""}: ${fmtNum(Number(ob.base_m) || 0)}–${fmtNum(top)} m high`);
      if (ob.kind === "prism" && Array.isArray(ob.footprint)) {
        obsG.append(s("polygon", { points: ob.footprint.map((v) => `${X(v[0])},${Y(v[1])}`).join(" "), fill: "#8a939e", "fill-opacity": 0.55, stroke: "#3b424a", "stroke-width": 1.2, class: "obstacle prism" }, title));
      } else if (ob.kind === "wall" && ob.start && ob.end) {
        obsG.append(s("line", { x1: X(ob.start[0]), y1: Y(ob.start[1]), x2: X(ob.end[0]), y2: Y(ob.end[1]), stroke: "#3b424a", "stroke-width": 3.5, "stroke-linecap": "round", class: "obstacle wall" }, title));
      }
    }
    svg.append(obsG);
    // UE maps
    if ($("layer-ues").checked) {
      for (const layer of ueLayers()) {
        const g = s("g", { class: "ue-map", "data-name": layer.name, fill: layer.colour, "fill-opacity": 0.45 });
        const wmax = Math.max(...layer.map.weights, 1e-300);
        layer.map.points.forEach((p, i) => {
          g.append(s("circle", { cx: X(p[0]).toFixed(1), cy: Y(p[1]).toFixed(1), r: (1.4 + 2.6 * Math.sqrt(layer.map.weights[i] / wmax)).toFixed(2) }));
        });
        svg.append(g);
      }
    }
    // candidates and the shown layout
    const chosen = new Set(shownLayout());
    const colour = state.count ? colourOf(state.count) : "#1a1a1a";
    const candG = s("g", { id: "candidates" });
    for (const c of candidates()) {
      const isChosen = chosen.has(c.index);
      if (!isChosen && !$("layer-candidates").checked) continue;
      const [yaw, pitch] = c.orientation || [0, 0, 0];
      const px = X(c.position[0]);
      const py = Y(c.position[1]);
      const len = (isChosen ? 24 : 16) * Math.cos(pitch);
      const ax = px + len * Math.cos(yaw) * Math.cos(0);
      const ay = py - len * Math.sin(yaw);
      const sz = isChosen ? 11 : 7;
      const g = s("g", { class: isChosen ? "site chosen" : "site", "data-site": c.index });
      g.append(s("title", {}, `Site ${c.index}${c.name ? " – " + c.name : ""}: x ${fmtNum(c.position[0])} m, y ${fmtNum(c.position[1])} m, height ${fmtNum(c.position[2])} m, facing ${fmtNum(deg(yaw), 3)}°, tilt ${fmtNum(deg(pitch), 3)}° down` +
        (c.far_field_flag ? " (near field for part of the map)" : "")));
      g.append(s("line", { x1: px, y1: py, x2: ax, y2: ay, stroke: isChosen ? colour : "#4d5561", "stroke-width": isChosen ? 2.5 : 1.3, "marker-end": isChosen ? "url(#arrow-chosen)" : "url(#arrow)" }));
      g.append(s("rect", {
        x: px - sz / 2, y: py - sz / 2, width: sz, height: sz,
        fill: isChosen ? colour : "#ffffff", stroke: c.far_field_flag ? "#b35900" : "#1a1a1a", "stroke-width": isChosen ? 1.5 : 1.2,
      }));
      if (isChosen) g.append(s("text", { x: px + 8, y: py - 8, "font-size": 11, "font-weight": 700, fill: "#1a1a1a", stroke: "#ffffff", "stroke-width": 3, "paint-order": "stroke" }, `${c.index} (${fmtNum(c.position[2], 2)} m)`));
      candG.append(g);
    }
    const defs = s("defs");
    for (const [id, col] of [["arrow", "#4d5561"], ["arrow-chosen", colour]]) {
      defs.append(s("marker", { id, viewBox: "0 0 10 10", refX: 8, refY: 5, markerWidth: 6, markerHeight: 6, orient: "auto-start-reverse" },
        s("path", { d: "M0,0 L10,5 L0,10 z", fill: col })));
    }
    svg.append(defs, candG);
    // scale bar
    const barM = niceStep((b.x1 - b.x0), 5);
    const bx = 55;
    const by = Hmax - 10;
    svg.append(s("g", { class: "scale" },
      s("line", { x1: bx, y1: by, x2: bx + barM * k, y2: by, stroke: "#1a1a1a", "stroke-width": 3 }),
      s("text", { x: bx + barM * k + 6, y: by + 4, "font-size": 11, fill: "#1a1a1a" }, `${fmtNum(barM, 3)} m`)));
    svg.append(s("g", { id: "selection" }));
    drawSelection();
  }

  function shownLayout() {
    const entry = state.count ? countEntry(state.count) : null;
    if (!entry) return [];
    const lay = entry.top_layouts[state.layoutIdx] || entry.top_layouts[0];
    return lay ? lay.sites : entry.sites;
  }

  /** Colour range of the shown count's heatmap (finite cells), log scale. */
  function heatRange() {
    const grid = state.plan.heatmap.bound_m[state.count] || [];
    let lo = Infinity, hi = -Infinity;
    for (const row of grid) for (const v of row) if (v !== null && v > 0) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (!Number.isFinite(lo)) return null;
    if (hi <= lo * 1.0001) hi = lo * 1.01;
    return { lo, hi };
  }

  function drawHeatmap(svg, X, Y, k) {
    const hm = state.plan.heatmap;
    const grid = hm.bound_m[state.count];
    const blind = hm.blind[state.count];
    if (!grid) return;
    const g = hm.grid;
    const range = heatRange();
    if ($("layer-heatmap").checked) {
      const canvas = document.createElement("canvas");
      canvas.width = g.nx;
      canvas.height = g.ny;
      const ctx = canvas.getContext("2d");
      const img = ctx.createImageData(g.nx, g.ny);
      for (let iy = 0; iy < g.ny; iy++) {
        for (let ix = 0; ix < g.nx; ix++) {
          const v = grid[iy][ix];
          const o = ((g.ny - 1 - iy) * g.nx + ix) * 4;
          let rgb = null;
          if (v !== null && range) rgb = viridis((Math.log10(v) - Math.log10(range.lo)) / (Math.log10(range.hi) - Math.log10(range.lo)));
          else if (blind[iy][ix]) rgb = [0xd7, 0x30, 0x1f];
          if (rgb) { img.data[o] = rgb[0]; img.data[o + 1] = rgb[1]; img.data[o + 2] = rgb[2]; img.data[o + 3] = 235; }
        }
      }
      ctx.putImageData(img, 0, 0);
      svg.append(s("image", {
        id: "heatmap-image", href: canvas.toDataURL("image/png"),
        x: X(g.x0 - g.cell_m / 2), y: Y(g.y0 + (g.ny - 0.5) * g.cell_m),
        width: g.nx * g.cell_m * k, height: g.ny * g.cell_m * k,
        preserveAspectRatio: "none",
      }));
    }
    const level = hm.threshold_m[state.count];
    if ($("layer-contour").checked && level) {
      const d = contourPath(grid, blind, g, level, X, Y);
      if (d) {
        svg.append(s("path", { d, fill: "none", stroke: "#ffffff", "stroke-width": 4, "stroke-linecap": "round" }));
        svg.append(s("path", { id: "contour", d, fill: "none", stroke: "#1a1a1a", "stroke-width": 1.8, "stroke-linecap": "round" }));
      }
    }
  }

  /** Marching squares between cell centres at the (log) level; blind cells count as above it. */
  function contourPath(grid, blind, g, level, X, Y) {
    const L = Math.log10(level);
    const val = (ix, iy) => {
      const v = grid[iy][ix];
      if (v !== null) return Math.log10(v);
      return blind[iy][ix] ? L + 10 : NaN;
    };
    const cx = (ix) => g.x0 + ix * g.cell_m;
    const cy = (iy) => g.y0 + iy * g.cell_m;
    const CASES = { 1: [[2, 3]], 2: [[1, 2]], 3: [[1, 3]], 4: [[0, 1]], 5: [[0, 3], [1, 2]], 6: [[0, 2]], 7: [[0, 3]],
      8: [[0, 3]], 9: [[0, 2]], 10: [[0, 1], [2, 3]], 11: [[0, 1]], 12: [[1, 3]], 13: [[1, 2]], 14: [[2, 3]] };
    const parts = [];
    for (let iy = 0; iy + 1 < g.ny; iy++) {
      for (let ix = 0; ix + 1 < g.nx; ix++) {
        const a = val(ix, iy), b = val(ix + 1, iy), c = val(ix + 1, iy + 1), d = val(ix, iy + 1);
        if ([a, b, c, d].some(Number.isNaN)) continue;
        const idx = (a > L ? 8 : 0) | (b > L ? 4 : 0) | (c > L ? 2 : 0) | (d > L ? 1 : 0);
        const segs = CASES[idx];
        if (!segs) continue;
        const t = (p, q) => (p === q ? 0.5 : Math.min(1, Math.max(0, (L - p) / (q - p))));
        const edge = [
          () => [cx(ix) + t(a, b) * g.cell_m, cy(iy)],
          () => [cx(ix + 1), cy(iy) + t(b, c) * g.cell_m],
          () => [cx(ix + 1) - t(c, d) * g.cell_m, cy(iy + 1)],
          () => [cx(ix), cy(iy + 1) - t(d, a) * g.cell_m],
        ];
        for (const [e1, e2] of segs) {
          const p = edge[e1]();
          const q = edge[e2]();
          parts.push(`M${X(p[0]).toFixed(1)},${Y(p[1]).toFixed(1)}L${X(q[0]).toFixed(1)},${Y(q[1]).toFixed(1)}`);
        }
      }
    }
    return parts.join("");
  }

  function drawLegend() {
    const box = clear($("legend"));
    if (!state.view) return;
    for (const layer of ueLayers()) {
      const note = layer.map.stride > 1 ? ` (every ${layer.map.stride}th of ${layer.map.total})` : ` (${layer.map.total} points; size ∝ weight)`;
      box.append(h("span", {}, h("span", { class: "swatch", "data-colour": layer.colour }), layer.name + note));
    }
    box.append(h("span", {}, "□ → candidate site, arrow = facing (shorter when tilted)"));
    if (obstacles().length) box.append(h("span", {}, "▩ obstacle (prism), ▬ wall"));
    const plan = state.plan;
    if (plan && plan.heatmap && state.count) {
      const range = heatRange();
      const metric = METRIC_LABEL[plan.heatmap.metric] || "bound";
      if (range && $("layer-heatmap").checked) {
        const stops = VIRIDIS.map((c, i) => `${c} ${(100 * i) / (VIRIDIS.length - 1)}%`).join(", ");
        const bar = h("span", { class: "bar", "data-gradient": stops });
        const mid = Math.sqrt(range.lo * range.hi);
        box.append(h("span", { class: "cb" },
          h("span", {}, `${metric} [m], ${state.count} RIS (log scale) `, bar),
          h("span", { class: "ticks" }, h("span", { text: fmtNum(range.lo) }), h("span", { text: fmtNum(mid) }), h("span", { text: fmtNum(range.hi) }))));
      }
      box.append(h("span", {}, h("span", { class: "swatch", "data-colour": BLIND_COLOUR }), "blind (bound ∞)"));
      if ($("layer-contour").checked) box.append(h("span", {}, `— contour at ${plan.heatmap.threshold_label} (${fmtM(plan.heatmap.threshold_m[state.count])})`));
      box.append(h("span", {}, h("span", { class: "swatch", "data-colour": colourOf(state.count) }), `layout shown: sites ${shownLayout().join(", ")}`));
    }
    // colours via CSSOM (the page's CSP allows no inline style attributes)
    for (const el of box.querySelectorAll("[data-colour]")) el.style.background = el.dataset.colour;
    for (const el of box.querySelectorAll("[data-gradient]")) el.style.background = `linear-gradient(to right, ${el.dataset.gradient})`;
  }

  function renderSites() {
    const table = clear($("sites-table"));
    const cands = candidates();
    $("sites-details").querySelector("summary").textContent = `Candidate sites (${cands.length})`;
    if (!cands.length) return;
    table.append(h("thead", {}, h("tr", {}, ["#", "Name", "x [m]", "y [m]", "Height [m]", "Facing [°]", "Tilt down [°]"].map((t) => h("th", { scope: "col", text: t })))));
    const tb = h("tbody");
    const chosen = new Set(shownLayout());
    for (const c of cands) {
      const o = c.orientation || [0, 0, 0];
      tb.append(h("tr", { class: chosen.has(c.index) ? "current" : null },
        h("td", { text: c.index }), h("td", { text: c.name || "" }),
        h("td", { text: fmtNum(c.position[0]) }), h("td", { text: fmtNum(c.position[1]) }), h("td", { text: fmtNum(c.position[2]) }),
        h("td", { text: fmtNum(deg(o[0]), 3) }), h("td", { text: fmtNum(deg(o[1]), 3) })));
    }
    table.append(tb);
  }

  // ---------------------------------------------------------------- per-point results
  function pointGroups() {
    if (!state.plan || !state.plan.points) return [];
    if (state.groups && state.groups.plan === state.plan) return state.groups.list;
    const byKey = new Map();
    for (const p of state.plan.points) {
      const key = `${p.position[0].toFixed(6)},${p.position[1].toFixed(6)}`;
      if (!byKey.has(key)) byKey.set(key, { x: p.position[0], y: p.position[1], members: [] });
      byKey.get(key).members.push(p.index);
    }
    const list = [...byKey.values()];
    state.groups = { plan: state.plan, list };
    return list;
  }

  function nearestGroup(x, y, maxDist) {
    let best = null;
    let bd = Infinity;
    for (const g of pointGroups()) {
      const d = (g.x - x) ** 2 + (g.y - y) ** 2;
      if (d < bd) { bd = d; best = g; }
    }
    return best && Math.sqrt(bd) <= maxDist ? best : null;
  }

  function groupOf(index) {
    return pointGroups().find((g) => g.members.includes(index)) || null;
  }

  function drawSelection() {
    const sel = document.getElementById("selection");
    if (!sel) return;
    clear(sel);
    if (state.selected === null || !state.view) return;
    const p = state.plan.points[state.selected];
    const { X, Y } = state.view;
    sel.append(s("circle", { cx: X(p.position[0]), cy: Y(p.position[1]), r: 8, fill: "none", stroke: "#ffffff", "stroke-width": 4 }));
    sel.append(s("circle", { cx: X(p.position[0]), cy: Y(p.position[1]), r: 8, fill: "none", stroke: "#c25400", "stroke-width": 2.2 }));
  }

  function renderPointInfo() {
    const box = $("point-info");
    if (state.selected === null || !state.plan) {
      clear(box).append(state.plan
        ? "Click a point of the RX map (or focus the map and use the arrow keys) to read its bound, serving RISs and blind reason."
        : "Load a document to see the site; after a job, click a point of the RX map to read its result.");
      return;
    }
    const group = groupOf(state.selected) || { members: [state.selected] };
    const first = state.plan.points[group.members[0]];
    clear(box);
    box.append(h("p", {}, h("strong", { text: `RX point at x ${fmtNum(first.position[0])} m, y ${fmtNum(first.position[1])} m` }),
      ` – shown count: ${state.count} RIS; bound = ${METRIC_LABEL[state.plan.objective.metric] || "bound"}, weighted median over the TX map`));
    const counts = state.plan.by_count.map((b) => String(b.ris_count));
    const table = h("table", { class: "point-table" });
    table.append(h("thead", {}, h("tr", {}, h("th", { scope: "col", text: "z [m]" }), h("th", { scope: "col", text: "weight" }),
      counts.map((c) => h("th", { scope: "col", text: `${c} RIS: bound · serving` })))));
    const tb = h("tbody");
    for (const idx of group.members) {
      const p = state.plan.points[idx];
      tb.append(h("tr", { class: idx === state.selected ? "current" : null, "data-point": idx },
        h("td", { text: fmtNum(p.position[2]) }), h("td", { text: fmtNum(p.weight) }),
        counts.map((c) => {
          const b = p.bound_m[c];
          const reason = p.reason[c];
          const serving = p.serving[c] || [];
          return h("td", { class: c === state.count ? "shown-count" : null, "data-count": c },
            h("span", { class: "bound", text: b === null ? "no bound" : `${fmtNum(b)} m` }),
            ` · sites ${serving.length ? serving.join(", ") : "none"}`,
            reason ? h("div", { class: "reason", text: `blind: ${reason}` }) : null);
        })));
    }
    table.append(tb);
    box.append(h("div", { class: "table-wrap" }, table));
  }

  function selectPoint(index) {
    state.selected = index;
    drawSelection();
    renderPointInfo();
  }

  function onMapClick(ev) {
    if (!state.view || !state.plan || !state.plan.points) return;
    const rect = $("map").getBoundingClientRect();
    const vb = $("map").viewBox.baseVal;
    const px = ((ev.clientX - rect.left) / rect.width) * vb.width;
    const py = ((ev.clientY - rect.top) / rect.height) * vb.height;
    const [x, y] = state.view.inv(px, py);
    const g = nearestGroup(x, y, 20 / state.view.k);
    if (g) selectPoint(g.members[0]);
  }

  let hoverPending = null;
  function onMapHover(ev) {
    if (!state.view || !state.plan || !state.plan.points) return;
    hoverPending = ev;
    requestAnimationFrame(() => {
      if (!hoverPending) return;
      const e = hoverPending;
      hoverPending = null;
      const rect = $("map").getBoundingClientRect();
      const vb = $("map").viewBox.baseVal;
      const px = ((e.clientX - rect.left) / rect.width) * vb.width;
      const py = ((e.clientY - rect.top) / rect.height) * vb.height;
      const [x, y] = state.view.inv(px, py);
      const g = nearestGroup(x, y, 12 / state.view.k);
      const tip = $("tooltip");
      if (!g) { tip.hidden = true; return; }
      const vals = g.members.map((i) => state.plan.points[i].bound_m[state.count]);
      const txt = vals.map((v) => (v === null ? "∞" : fmtNum(v))).join(" / ");
      tip.textContent = `(${fmtNum(g.x)}, ${fmtNum(g.y)}) m: ${txt} m at ${state.count} RIS`;
      tip.style.left = `${e.clientX - rect.left + 14}px`;
      tip.style.top = `${e.clientY - rect.top + 10}px`;
      tip.hidden = false;
    });
  }

  function onMapKey(ev) {
    const dirs = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] };
    const dir = dirs[ev.key];
    if (!dir || !state.plan || !state.plan.points) return;
    ev.preventDefault();
    const groups = pointGroups();
    if (!groups.length) return;
    const cur = state.selected === null ? null : groupOf(state.selected);
    if (!cur) { selectPoint(groups[0].members[0]); return; }
    let best = null;
    let bs = Infinity;
    for (const g of groups) {
      const dx = g.x - cur.x;
      const dy = g.y - cur.y;
      const along = dx * dir[0] + dy * dir[1];
      if (along <= 1e-9) continue;
      const across = Math.abs(dx * dir[1] - dy * dir[0]);
      const score = along + 2 * across;
      if (score < bs) { bs = score; best = g; }
    }
    if (best) selectPoint(best.members[0]);
  }

  // ---------------------------------------------------------------- start
  function init() {
    $("banner-close").addEventListener("click", hideBanner);
    $("load-preset").addEventListener("click", loadPreset);
    $("upload").addEventListener("change", uploadDocument);
    $("upload-geojson").addEventListener("change", importGeojson);
    $("f-objective-kind").addEventListener("change", updateLevelField);
    $("validate").addEventListener("click", validate);
    $("params").addEventListener("submit", submit);
    $("cancel").addEventListener("click", cancelJob);
    $("refresh-jobs").addEventListener("click", refreshJobs);
    $("api-key").value = state.apiKey;
    $("api-key-form").addEventListener("submit", (ev) => {
      ev.preventDefault();
      state.apiKey = $("api-key").value.trim();
      sessionStorage.setItem("rp.apiKey", state.apiKey);
      $("api-key-status").textContent = state.apiKey ? "Key set for this tab." : "No key: requests are sent without one.";
      loadPresets();
      refreshJobs();
    });
    for (const id of ["layer-heatmap", "layer-contour", "layer-ues", "layer-candidates"]) $(id).addEventListener("change", drawAll);
    const map = $("map");
    map.addEventListener("click", onMapClick);
    map.addEventListener("mousemove", onMapHover);
    map.addEventListener("mouseleave", () => { $("tooltip").hidden = true; });
    map.addEventListener("keydown", onMapKey);
    let resizeTimer = null;
    window.addEventListener("resize", () => {
      clearTimeout(resizeTimer);
      resizeTimer = setTimeout(() => { drawAll(); if (state.plan) { drawCdf(); drawGain(); } }, 150);
    });
    drawAll();
    checkHealth();
    inspectServer();
    loadPresets();
    refreshJobs();
  }

  window.risPlanner = { state, jobFiles }; // for debugging and the browser tests
  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", init);
  else init();
})();
