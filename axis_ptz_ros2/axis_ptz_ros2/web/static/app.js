// Axis PTZ console: mouse teleop (thesis §3.4.5), keyboard shortcuts of the keyboard teleop, quality
// controls and live readouts. Plain JavaScript, no build step, no external resources.
"use strict";

const $ = (id) => document.getElementById(id);
const state = {
  mouse: { shift_zoom_delta: 2000, ctrl_zoom_delta: -5000 },
  keys: new Map(),
  formDirty: false,
  limits: null,
  stillSeq: 0,
};

// ------------------------------------------------------------------------------------------------------
// message line and HTTP helpers
// ------------------------------------------------------------------------------------------------------
function say(text, ok) {
  const m = $("message");
  m.textContent = text;
  m.className = "message " + (ok ? "ok" : "bad");
}

async function post(path, body) {
  let res;
  try {
    res = await fetch(path, {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify(body),
      credentials: "same-origin",
    });
  } catch (err) {
    say(`console not reachable: ${err}`, false);
    return null;
  }
  let answer;
  try {
    answer = await res.json();
  } catch (_err) {
    answer = { ok: false, message: `HTTP ${res.status}` };
  }
  say(answer.message || (answer.ok ? "ok" : `HTTP ${res.status}`), answer.ok);
  return answer;
}

// The rectangle the picture occupies inside an <img> box: the whole box when the box has the picture's
// aspect (the layout keeps it so), else the centred, letterboxed part (object-fit: contain), so a click maps
// to the right pixel whatever the image's aspect (704x576 PAL, 1920x1080 HD, ...) and the window's shape.
function naturalSize(el) {
  return el.tagName === "CANVAS" ? [el.width, el.height] : [el.naturalWidth, el.naturalHeight];
}

function pictureRect(img) {
  const r = img.getBoundingClientRect();
  const [w, h] = naturalSize(img);
  if (!w || !h || r.width <= 0 || r.height <= 0) return null;
  const scale = Math.min(r.width / w, r.height / h);
  const pw = w * scale;
  const ph = h * scale;
  return { left: r.left + (r.width - pw) / 2, top: r.top + (r.height - ph) / 2, width: pw, height: ph, w, h };
}

// Pixel of a mouse event in the image's own (natural) pixels: the displayed size may differ. Pixel
// coordinates follow geometry.py: pixel i covers [i - 0.5, i + 0.5), so the image centre is (w - 1) / 2.
function naturalPixel(img, ev) {
  const r = pictureRect(img);
  if (!r) return null;
  const x = ((ev.clientX - r.left) * r.w) / r.width - 0.5;
  const y = ((ev.clientY - r.top) * r.h) / r.height - 0.5;
  return { x: Math.min(Math.max(x, 0), r.w - 1), y: Math.min(Math.max(y, 0), r.h - 1), w: r.w, h: r.h };
}

// The stage is sized to the live image's own aspect (from its natural size, never assumed).
function updateAspect() {
  const [w, h] = naturalSize(h264.showing ? $("ptz-canvas") : $("ptz"));
  if (!w || !h) return;
  const aspect = String(w / h);
  const root = document.documentElement.style; // the stage and the side panel's width both follow it
  if (root.getPropertyValue("--ptz-aspect") !== aspect) root.setProperty("--ptz-aspect", aspect);
}

// ------------------------------------------------------------------------------------------------------
// video: reconnect a stream that broke (node restarted, network hiccup)
// ------------------------------------------------------------------------------------------------------
function keepAlive(img, urlFn) {
  img.addEventListener("error", () => {
    setTimeout(() => {
      if (img.id === "ptz" && h264.showing) return; // the H.264 canvas shows the PTZ video now
      img.src = `${urlFn()}?t=${Date.now()}`;
    }, 1000);
  });
}

function panoramaUrl() {
  return $("overlay").checked && state.overlayAvailable ? "/video/overlay.mjpg" : "/video/panorama.mjpg";
}

function updatePanoramaSource() {
  const want = panoramaUrl();
  const img = $("pano");
  if (new URL(img.src, location.href).pathname !== want) img.src = want;
}

// ------------------------------------------------------------------------------------------------------
// PTZ video as H.264, decoded here with WebCodecs and drawn on a canvas (web/h264relay.py has the wire
// format: per access unit u32 length, u8 flags (1 key, 2 catch-up), u8 codec length, f64 capture stamp,
// codec string, Annex B bytes). Which video the page opens is the console's decision (state.ptz_video.codec,
// by default the stream's own codec from video/params): H.264 only while the stream is H.264 (an MJPEG request
// beside it would pull the transcoder's compression-0 JPEGs over the link), MJPEG while it is MJPEG, nothing
// before the console knows. Falls back to the MJPEG <img> when the browser has no WebCodecs or cannot decode
// the stream's codec; after a decode error the decoder is recreated and waits for the next key frame (the
// console passes the error on as link feedback: the stream node sends an IDR).
// ------------------------------------------------------------------------------------------------------
const h264 = {
  running: false, // a /video/ptz.h264 request is open
  showing: false, // the canvas (not the MJPEG <img>) shows the PTZ video
  decoder: null,
  codec: "",
  waitKey: true,
  decoded: 0, // frames decoded by this page (shown on the canvas or catch-up)
  errors: 0, // decode errors and frames skipped while waiting for a key frame after one
  sent: { decoded: 0, errors: 0 },
  note: "",
  retryAt: 0,
  lastStamp: 0,
  abort: null, // the AbortController of the open /video/ptz.h264 request
};
const H264_ALLOWED = new URLSearchParams(location.search).get("video") !== "mjpeg";

function showMjpeg(note) {
  h264.note = note;
  if (!h264.showing && $("ptz").getAttribute("src")) return;
  h264.showing = false;
  $("ptz-canvas").hidden = true;
  const img = $("ptz");
  img.hidden = false;
  img.src = `/video/ptz.mjpg?t=${Date.now()}`;
}

function showCanvas() {
  if (h264.showing) return;
  h264.showing = true;
  h264.note = "";
  $("ptz-canvas").hidden = false;
  const img = $("ptz");
  img.hidden = true;
  img.removeAttribute("src"); // ends the MJPEG request: the console unsubscribes from the JPEG topic
  updateAspect();
}

function closeDecoder() {
  if (h264.decoder && h264.decoder.state !== "closed") {
    try {
      h264.decoder.close();
    } catch (_err) {
      /* already closed */
    }
  }
  h264.decoder = null;
}

function newDecoder(codec) {
  closeDecoder();
  const canvas = $("ptz-canvas");
  const ctx = canvas.getContext("2d");
  const dec = new VideoDecoder({
    output: (frame) => {
      h264.decoded += 1;
      const draw = frame.timestamp >= 0; // catch-up frames carry a negative timestamp: decoded, not drawn
      if (draw) {
        if (canvas.width !== frame.displayWidth || canvas.height !== frame.displayHeight) {
          canvas.width = frame.displayWidth;
          canvas.height = frame.displayHeight;
        }
        ctx.drawImage(frame, 0, 0, canvas.width, canvas.height);
        canvas.dataset.frames = String(h264.decoded);
        showCanvas();
      }
      frame.close();
    },
    error: (err) => {
      h264.errors += 1;
      h264.note = `decode error: ${err.message || err}`;
      h264.waitKey = true; // the decoder is closed now: a new one starts at the next key frame
      h264.decoder = null;
    },
  });
  dec.configure({ codec, optimizeForLatency: true });
  h264.decoder = dec;
  h264.codec = codec;
}

async function codecSupported(codec) {
  try {
    const r = await VideoDecoder.isConfigSupported({ codec, optimizeForLatency: true });
    return Boolean(r.supported);
  } catch (_err) {
    return false;
  }
}

async function onAccessUnit(flags, stamp, codec, data) {
  const key = (flags & 1) !== 0;
  const catchUp = (flags & 2) !== 0;
  if (h264.waitKey || !h264.decoder || codec !== h264.codec) {
    if (!key) {
      if (h264.codec) h264.errors += 1; // lost: waiting for the next key frame
      return true;
    }
    if (codec !== h264.codec && !(await codecSupported(codec))) {
      h264.note = `this browser cannot decode ${codec}`;
      return false;
    }
    newDecoder(codec);
    h264.waitKey = false;
  }
  h264.lastStamp = stamp;
  try {
    h264.decoder.decode(
      new EncodedVideoChunk({
        type: key ? "key" : "delta",
        timestamp: catchUp ? -1 : Math.round(stamp * 1e6),
        data,
      })
    );
  } catch (err) {
    h264.errors += 1;
    h264.note = `decode refused: ${err.message || err}`;
    h264.waitKey = true;
    closeDecoder();
  }
  return true;
}

async function runH264() {
  h264.running = true;
  h264.waitKey = true;
  h264.codec = "";
  let ok = true;
  try {
    h264.abort = new AbortController();
    const res = await fetch("/video/ptz.h264", {
      credentials: "same-origin",
      cache: "no-store",
      signal: h264.abort.signal,
    });
    if (!res.ok || !res.body) throw new Error(`HTTP ${res.status}`);
    const reader = res.body.getReader();
    let buf = new Uint8Array(0);
    while (ok) {
      const { value, done } = await reader.read();
      if (done) throw new Error("stream ended");
      const joined = new Uint8Array(buf.length + value.length);
      joined.set(buf);
      joined.set(value, buf.length);
      buf = joined;
      let off = 0;
      while (ok && buf.length - off >= 14) {
        const view = new DataView(buf.buffer, buf.byteOffset + off);
        const len = view.getUint32(0);
        if (buf.length - off < 4 + len) break;
        const flags = view.getUint8(4);
        const clen = view.getUint8(5);
        const stamp = view.getFloat64(6);
        const codec = new TextDecoder().decode(buf.subarray(off + 14, off + 14 + clen));
        const data = buf.slice(off + 14 + clen, off + 4 + len);
        off += 4 + len;
        ok = await onAccessUnit(flags, stamp, codec, data);
      }
      buf = buf.slice(off);
    }
    reader.cancel();
  } catch (err) {
    if (!h264.note) h264.note = `H.264 stream: ${err.message || err}`;
  }
  closeDecoder();
  h264.running = false;
  h264.abort = null;
  h264.retryAt = Date.now() + (ok ? 2000 : 30000);
  showMjpeg(h264.note);
}

function maybeStartH264(s) {
  if (h264.running || Date.now() < h264.retryAt) return;
  if (!H264_ALLOWED) {
    showMjpeg("MJPEG asked for (?video=mjpeg)");
    return;
  }
  if (typeof VideoDecoder === "undefined" || typeof EncodedVideoChunk === "undefined") {
    showMjpeg("no WebCodecs in this browser: MJPEG");
    return;
  }
  if (!s.h264 || !s.h264.available) {
    showMjpeg("no H.264 published: MJPEG");
    return;
  }
  runH264();
}

// The PTZ video the console gives (ptz_video.codec: "h264", "mjpeg", or "" while it waits for the stream's
// video/params): only that one is opened, and a change of the stream's codec switches the page over.
function choosePtzVideo(s) {
  const pv = s.ptz_video || { codec: "mjpeg", text: "" };
  if (pv.codec === "h264") {
    maybeStartH264(s);
  } else if (pv.codec === "mjpeg") {
    if (h264.running && h264.abort) {
      h264.note = "the stream is MJPEG now";
      h264.abort.abort(); // runH264 ends and shows the MJPEG <img>
    } else if (!h264.running) {
      showMjpeg("the stream is MJPEG");
    }
  } else if (!h264.showing && !$("ptz").getAttribute("src")) {
    h264.note = pv.text || "waiting for the stream's codec";
  }
}

async function reportDecoder() {
  const body = {
    mode: h264.showing ? "h264" : "mjpeg",
    decoded: h264.decoded - h264.sent.decoded,
    errors: h264.errors - h264.sent.errors,
    codec: h264.codec,
    note: h264.note.slice(0, 200),
  };
  const sent = { decoded: h264.decoded, errors: h264.errors, mode: body.mode, note: body.note };
  const old = h264.sent;
  if (!body.decoded && !body.errors && old.mode === body.mode && old.note === body.note) return;
  try {
    const res = await fetch("/api/decoder", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify(body),
      credentials: "same-origin",
    });
    if (res.ok) h264.sent = sent;
  } catch (_err) {
    /* the state poll shows the console as disconnected */
  }
}

// ------------------------------------------------------------------------------------------------------
// mouse teleop
// ------------------------------------------------------------------------------------------------------
function onPtzClick(ev) {
  ev.preventDefault();
  const p = naturalPixel(ev.currentTarget, ev);
  if (!p) {
    say("no PTZ image yet", false);
    return;
  }
  let zoomDelta = 0;
  if (ev.shiftKey) zoomDelta = state.mouse.shift_zoom_delta;
  else if (ev.ctrlKey || ev.metaKey) zoomDelta = state.mouse.ctrl_zoom_delta;
  post("/api/center", { u: p.x, v: p.y, width: p.w, height: p.h, zoom_delta: zoomDelta });
}

function onPanoramaDblClick(ev) {
  ev.preventDefault();
  const p = naturalPixel(ev.currentTarget, ev);
  if (!p) {
    say("no panorama image yet", false);
    return;
  }
  post("/api/look_panorama", { x: p.x, y: p.y, width: p.w, height: p.h });
}

// ------------------------------------------------------------------------------------------------------
// keyboard shortcuts: the keyboard teleop's own table, served by the console
// ------------------------------------------------------------------------------------------------
async function loadKeymap() {
  try {
    const res = await fetch("/api/keymap", { credentials: "same-origin" });
    const km = await res.json();
    const tbody = $("keys").querySelector("tbody");
    tbody.textContent = "";
    for (const k of km.keys) {
      state.keys.set(k.browser, k);
      const tr = document.createElement("tr");
      const th = document.createElement("th");
      th.scope = "row";
      const kbd = document.createElement("kbd");
      kbd.textContent = k.label;
      th.appendChild(kbd);
      const td = document.createElement("td");
      td.textContent = k.description;
      tr.append(th, td);
      tbody.appendChild(tr);
    }
  } catch (err) {
    say(`could not load the key map: ${err}`, false);
  }
}

function onKeyDown(ev) {
  const t = ev.target;
  if (t && (t.tagName === "INPUT" || t.tagName === "SELECT" || t.tagName === "TEXTAREA")) return;
  if (ev.ctrlKey || ev.altKey || ev.metaKey) return;
  const entry = state.keys.get(ev.key);
  if (!entry) return;
  ev.preventDefault();
  if (entry.kind === "help") {
    const d = $("keys-details");
    d.open = !d.open;
    return;
  }
  if (ev.repeat && entry.kind !== "pan" && entry.kind !== "tilt" && entry.kind !== "zoom") return;
  post("/api/key", { key: entry.key });
}

// ------------------------------------------------------------------------------------------------------
// quality controls
// ------------------------------------------------------------------------------------------------------
// the accepted ranges come with the state (the console's API table: the stream node's parameter ranges)
function applyLimits(limits) {
  if (!limits) return;
  state.limits = limits;
  for (const [id, name] of [["q-fps", "fps"], ["q-comp", "compression"], ["q-budget", "max_bitrate_kbps"]]) {
    const range = limits[name];
    if (!range) continue;
    const el = $(id);
    if (el.min !== String(range[0])) el.min = range[0];
    if (el.max !== String(range[1])) el.max = range[1];
  }
  const c = limits.compression;
  if (c) $("q-comp-note").textContent = `(${c[0]} best – ${c[1]} smallest)`;
}

function fillQuality(video, resolutions) {
  if (!video || state.formDirty) return;
  $("q-fps").value = video.fps;
  const sel = $("q-res");
  const list = resolutions && resolutions.length ? resolutions.slice() : [];
  if (video.resolution && !list.includes(video.resolution)) list.push(video.resolution);
  const current = Array.from(sel.options).map((o) => o.value).join(",");
  if (current !== list.join(",")) {
    sel.textContent = "";
    for (const r of list) {
      const o = document.createElement("option");
      o.value = r;
      o.textContent = r;
      sel.appendChild(o);
    }
  }
  sel.value = video.resolution;
  $("q-comp").value = video.compression;
  $("q-comp-out").textContent = video.compression;
  $("q-budget").value = video.max_bitrate_kbps;
  // what the form showed: Apply sends only what the operator changed (never pins values the stream's
  // bandwidth budget or link adaptation chose for the moment)
  state.shown = {
    fps: video.fps,
    resolution: video.resolution,
    compression: video.compression,
    max_bitrate_kbps: video.max_bitrate_kbps,
  };
}

async function onQualitySubmit(ev) {
  ev.preventDefault();
  const shown = state.shown || {};
  const form = {
    fps: parseInt($("q-fps").value, 10),
    resolution: $("q-res").value,
    compression: parseInt($("q-comp").value, 10),
    max_bitrate_kbps: parseInt($("q-budget").value, 10),
  };
  const body = {};
  for (const [k, v] of Object.entries(form)) if (v !== shown[k]) body[k] = v;
  const fpsRange = state.limits && state.limits.fps;  // unknown yet: the console refuses with its reason
  if ("fps" in body && fpsRange && !(body.fps >= fpsRange[0] && body.fps <= fpsRange[1])) {
    say(`frame rate must be ${fpsRange[0]}..${fpsRange[1]}`, false);
    return;
  }
  if ("max_bitrate_kbps" in body && !(body.max_bitrate_kbps >= 0)) delete body.max_bitrate_kbps;
  if (Object.keys(body).length === 0) {
    say("nothing changed", false);
    state.formDirty = false;
    return;
  }
  const answer = await post("/api/video", body);
  if (answer && answer.ok) state.formDirty = false;
}

// ------------------------------------------------------------------------------------------------------
// live readouts
// ------------------------------------------------------------------------------------------------------
const fmt = (v, digits, unit) => (v === null || v === undefined ? "–" : `${Number(v).toFixed(digits)}${unit}`);

function render(s) {
  updateAspect();
  state.mouse = s.mouse || state.mouse;
  $("shift-delta").textContent = `${state.mouse.shift_zoom_delta >= 0 ? "+" : ""}${state.mouse.shift_zoom_delta}`;
  $("ctrl-delta").textContent = `${state.mouse.ctrl_zoom_delta >= 0 ? "+" : ""}${state.mouse.ctrl_zoom_delta}`;
  const p = s.ptz;
  if (p) {
    $("r-pan").textContent = `${fmt(p.pan_deg, 2, "°")} (${fmt(p.pan_rad, 4, " rad")})`;
    $("r-tilt").textContent = `${fmt(p.tilt_deg, 2, "°")} (${fmt(p.tilt_rad, 4, " rad")})`;
    $("r-zoom").textContent = `${fmt(p.zoom, 0, "")} (${fmt(p.magnification, 2, "×")})${p.moving ? " moving" : ""}`;
    $("r-fov").textContent = `${fmt(p.hfov_deg, 1, "°")} × ${fmt(p.vfov_deg, 1, "°")}`;
  }
  // drive-safe zoom: the PTZ node holds the zoom at its cap while the robot moves
  const cap = $("cap");
  const capped = Boolean(p && p.zoom_capped);
  cap.hidden = !capped;
  if (capped) {
    const over = p.requested_zoom !== null && p.requested_zoom > p.zoom_cap;
    const asked = over ? `, ${fmt(p.requested_zoom, 0, "")} asked` : "";
    cap.textContent = `zoom capped while driving (at ${fmt(p.zoom_cap, 0, "")}${asked})`;
    $("r-zoom").textContent += " · capped";
  }
  const st = s.stream || {};
  const drv = s.driver || {};
  const fps = st.measured_at === "console" ? st.fps : parseFloat(drv.fps);
  const kbps = st.measured_at === "console" ? st.kbps : parseFloat(drv["kbit/s"]);
  $("r-fps").textContent = fmt(Number.isFinite(fps) ? fps : null, 1, " fps");
  $("r-kbps").textContent = fmt(Number.isFinite(kbps) ? kbps : null, 0, " kbit/s");
  $("r-latency").textContent = fmt(st.latency_ms, 0, " ms");
  const mjpegOpen = Boolean($("ptz").getAttribute("src"));
  $("r-decoder").textContent = h264.showing
    ? `H.264 ${h264.codec} · ${h264.decoded} frames, ${h264.errors} errors`
    : mjpegOpen
      ? `MJPEG${h264.note ? ` (${h264.note})` : ""}`
      : h264.running
        ? "H.264: waiting for a key frame"
        : h264.note || "no video yet";
  choosePtzVideo(s);
  const v = s.video;
  if (v) {
    $("r-video").textContent = v.text;  // worded by the console (web/view.py video_text), as its answers are
    $("r-budget").textContent = v.max_bitrate_kbps ? `${v.max_bitrate_kbps} kbit/s` : "off";
  }
  applyLimits(s.limits);
  fillQuality(v, s.resolutions);
  const c = s.last_click;
  $("r-depth").textContent = c ? `${c.depth_source}, ${fmt(c.range_m, 1, " m")}` : "–";
  $("r-step").textContent = s.step ?? "–";
  state.overlayAvailable = Boolean(s.panorama && s.panorama.overlay);
  $("overlay-note").textContent = state.overlayAvailable ? "" : "(visualizer not running)";
  updatePanoramaSource();
  showStill(s.still);
  const ul = $("errors");
  const errs = (s.errors || []).slice(-5).reverse();
  const text = errs.map((e) => `${new Date(e.time * 1000).toLocaleTimeString()} ${e.message}`);
  if (Array.from(ul.children).map((li) => li.textContent).join("\n") !== text.join("\n")) {
    ul.textContent = "";
    for (const t of text) {
      const li = document.createElement("li");
      li.textContent = t;
      ul.appendChild(li);
    }
  }
}

// ------------------------------------------------------------------------------------------------------
// full-quality still: the Still button (and key P) ask the stream node for one (still/capture); every new still
// (from this page or another) is shown beside the live view from /video/still.jpg
// ------------------------------------------------------------------------------------------------------
function showStill(info) {
  if (!info || !info.seq || info.seq === state.stillSeq) return;
  state.stillSeq = info.seq;
  $("still").src = `/video/still.jpg?seq=${info.seq}`;
  const size = info.width ? `${info.width}x${info.height}, ` : "";
  const when = info.stamp ? new Date(info.stamp * 1000).toLocaleTimeString() : "";
  $("still-info").textContent = `${size}${Math.round((info.bytes || 0) / 1024)} kB, ${when}`;
  $("still-figure").hidden = false;
}

async function takeStill() {
  const button = $("still-take");
  button.disabled = true;
  say("taking a still…", true);
  try {
    const answer = await post("/api/still", {});
    if (answer && answer.ok && answer.seq) {
      const res = await fetch("/api/state", { credentials: "same-origin", cache: "no-store" });
      if (res.ok) showStill((await res.json()).still);
    }
  } finally {
    button.disabled = false;
  }
}

async function poll() {
  const link = $("link");
  try {
    const res = await fetch("/api/state", { credentials: "same-origin", cache: "no-store" });
    if (res.status === 401) {
      location.reload(); // token changed or cookie gone: the server answers the page with its sign-in form
      return;
    }
    if (!res.ok) throw new Error(`HTTP ${res.status}`);
    render(await res.json());
    reportDecoder();
    link.textContent = "connected";
    link.className = "badge ok";
  } catch (err) {
    link.textContent = `disconnected (${err.message || err})`;
    link.className = "badge bad";
  }
  setTimeout(poll, 500);
}

// ------------------------------------------------------------------------------------------------------
function main() {
  const ptz = $("ptz");
  const pano = $("pano");
  const canvas = $("ptz-canvas");
  ptz.addEventListener("click", onPtzClick);
  canvas.addEventListener("click", onPtzClick);
  canvas.addEventListener("contextmenu", (ev) => ev.ctrlKey && ev.preventDefault());
  ptz.addEventListener("load", updateAspect);
  ptz.addEventListener("contextmenu", (ev) => ev.ctrlKey && ev.preventDefault());
  pano.addEventListener("dblclick", onPanoramaDblClick);
  keepAlive(ptz, () => "/video/ptz.mjpg");
  keepAlive(pano, panoramaUrl);
  $("overlay").addEventListener("change", updatePanoramaSource);
  $("home").addEventListener("click", () => post("/api/home", {}));
  $("still-take").addEventListener("click", takeStill);
  const form = $("quality");
  form.addEventListener("submit", onQualitySubmit);
  form.addEventListener("input", () => {
    state.formDirty = true;
    $("q-comp-out").textContent = $("q-comp").value;
  });
  document.addEventListener("keydown", onKeyDown);
  loadKeymap();
  poll();
}

document.addEventListener("DOMContentLoaded", main);
