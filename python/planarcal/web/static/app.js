// The live setup page of `planarcal live` (docs/live.md is the contract: GET /api/state and the actions).
// Plain JavaScript, no build step: one poll loop renders the state, every button posts one request.
"use strict";

(function () {
  const POLL_MS = 250;
  const FRAME_POLL_MS = 100;
  const MODES = ["setup", "register", "watch"];

  const $ = (id) => document.getElementById(id);

  let state = null;
  // The last rendered JSON of each section: a section is rebuilt only when its data changed.
  const rendered = {};
  let pollTimer = null;
  let pollInFlight = false;
  let pollFailed = false;
  let framePolling = false; // the stream failed: /api/frame.jpg is polled instead
  let actionsDone = 0; // actions ended so far: a poll begun before one ended is stale
  let shownMode = null;
  let picked = null; // the last POST /api/pick answer
  let settingsDirty = false;
  let coverageStamp = 0;

  // ---- messages ----------------------------------------------------------------------------

  // Where the message came from: a failing poll's message is cleared when polling recovers,
  // an action's message stays until the next action or a dismissal.
  let messageSource = null;

  function showMessage(text, source) {
    $("message").textContent = text;
    $("message-bar").hidden = false;
    messageSource = source || "action";
  }

  function clearMessage(source) {
    if (source && messageSource !== source) return;
    $("message").textContent = "";
    $("message-bar").hidden = true;
    messageSource = null;
  }

  // ---- requests ----------------------------------------------------------------------------

  // An error whose message is for the user (#message): a failed request or an input to fix.
  class ShownError extends Error {}

  // The server's {"error": ...} text, else the status line: never an empty message.
  async function errorText(response, method, path) {
    let text = "";
    try {
      text = await response.text();
      const body = JSON.parse(text);
      if (body && typeof body.error === "string" && body.error) return body.error;
    } catch (_) {
      // not JSON: fall through to the status line
    }
    const detail = text && text.length < 300 ? ": " + text.trim() : "";
    return method + " " + path + " failed (" + response.status + " " + response.statusText + ")" + detail;
  }

  async function request(method, path, body, contentType) {
    const init = { method: method, credentials: "same-origin", headers: {} };
    if (body !== undefined) {
      if (contentType) {
        init.headers["Content-Type"] = contentType;
        init.body = body;
      } else {
        init.headers["Content-Type"] = "application/json";
        init.body = JSON.stringify(body);
      }
    }
    let response;
    try {
      response = await fetch(path, init);
    } catch (err) {
      throw new ShownError("cannot reach the server (" + method + " " + path + "): " + err.message);
    }
    if (!response.ok) throw new ShownError(await errorText(response, method, path));
    const type = response.headers.get("Content-Type") || "";
    if (type.indexOf("application/json") >= 0) {
      try {
        return await response.json();
      } catch (err) {
        throw new ShownError(method + " " + path + " answered malformed JSON: " + err.message);
      }
    }
    return null;
  }

  // One user action: the button is busy while its request runs, a failure shows in #message,
  // and the state is polled at once after it.
  async function act(button, fn) {
    clearMessage();
    if (button) {
      button.disabled = true;
      button.setAttribute("aria-busy", "true");
    }
    try {
      const answer = await fn();
      // Most actions answer the new state: draw it at once rather than on the next poll.
      if (answer && typeof answer === "object" && typeof answer.version === "number" && answer.mode) {
        render(answer);
      }
      return answer;
    } catch (err) {
      showMessage(err instanceof ShownError ? err.message : "the page failed: " + err.message);
      if (!(err instanceof ShownError)) console.error(err);
      return undefined;
    } finally {
      if (button) {
        button.disabled = false;
        button.removeAttribute("aria-busy");
      }
      actionsDone += 1;
      pollNow();
    }
  }

  // ---- polling -----------------------------------------------------------------------------

  async function poll() {
    if (pollInFlight) return;
    pollInFlight = true;
    clearTimeout(pollTimer);
    const actionsBefore = actionsDone;
    let again = false;
    try {
      const next = await request("GET", "/api/state");
      if (pollFailed) {
        pollFailed = false;
        clearMessage("poll");
        // The server is back (perhaps restarted): an ended stream does not resume by itself.
        if (messageSource === "image" || messageSource === "image-poll") clearMessage();
        startStream(true);
      }
      // A state asked for before an action ended may predate it (a deleted row would come back
      // for a moment): drop it and ask again.
      if (actionsBefore === actionsDone) render(next);
      else again = true;
    } catch (err) {
      pollFailed = true;
      showMessage(err.message, "poll");
    } finally {
      pollInFlight = false;
      pollTimer = setTimeout(poll, again ? 0 : POLL_MS);
    }
  }

  function pollNow() {
    if (!pollInFlight) {
      clearTimeout(pollTimer);
      poll();
    }
  }

  // ---- formatting --------------------------------------------------------------------------

  function num(value, digits) {
    if (value === null || value === undefined || Number.isNaN(value)) return "–";
    return Number(value).toFixed(digits);
  }

  // A coordinate as typed: up to three decimals, no trailing zeros.
  function short(value) {
    if (value === null || value === undefined) return "–";
    return String(Number(Number(value).toFixed(3)));
  }

  function percent(share) {
    if (share === null || share === undefined) return "–";
    return (100 * share).toFixed(share < 0.01 && share > 0 ? 2 : 1) + " %";
  }

  function el(tag, attrs, children) {
    const node = document.createElement(tag);
    if (attrs) {
      for (const key of Object.keys(attrs)) {
        const value = attrs[key];
        if (value === null || value === undefined || value === false) continue;
        if (key === "text") node.textContent = value;
        else if (key === "className") node.className = value;
        else node.setAttribute(key, value === true ? "" : value);
      }
    }
    for (const child of children || []) {
      if (child !== null && child !== undefined) {
        node.appendChild(typeof child === "string" ? document.createTextNode(child) : child);
      }
    }
    return node;
  }

  // A definition list from [term, value, className?] rows.
  function pairs(container, rows) {
    container.replaceChildren();
    for (const row of rows) {
      container.appendChild(el("dt", { text: row[0] }));
      container.appendChild(el("dd", { text: row[1], className: row[2] || null }));
    }
  }

  // True when `value` differs from what `key` last rendered (and remembers it).
  function changed(key, value) {
    const json = JSON.stringify(value === undefined ? null : value);
    if (rendered[key] === json) return false;
    rendered[key] = json;
    return true;
  }

  // ---- rendering ---------------------------------------------------------------------------

  function render(next) {
    state = next;
    // Every section compares its own data with what it last drew, so only what changed is
    // rebuilt (a list being clicked is not replaced under the pointer). Not state.version alone:
    // detection, focus, stats and parts follow the frames and may change without a new version.
    renderMode(next.mode);
    renderAbout(next);
    renderError(next.error);
    renderDetection(next.detection, next.board);
    renderFocus(next.focus);
    renderPlacements(next.placements, next.coverage);
    renderCalibration(next.calibration, next.file);
    renderRegistration(next.registration);
    renderParts(next.watch);
    renderStats(next.stats);
    fitLive(); // the stream's frames may change size without a load event
    renderSettings(next.settings);
  }

  function renderMode(mode) {
    if (mode === shownMode || MODES.indexOf(mode) < 0) return;
    shownMode = mode;
    for (const m of MODES) {
      const tab = $("tab-" + m);
      const active = m === mode;
      tab.setAttribute("aria-selected", active ? "true" : "false");
      tab.classList.toggle("active", active);
      $("view-" + m).hidden = !active;
    }
    document.body.dataset.mode = mode;
    $("live-hint").textContent =
      mode === "register" ? "Click a dot or corner on the image to pick it." : "";
    if (mode !== "register") $("pick-marker").hidden = true;
    else placePickMarker();
  }

  function renderAbout(s) {
    const about = {
      source: s.source,
      board: s.board,
      file: s.file,
    };
    if (!changed("about", about)) return;
    const parts = [];
    if (s.source) {
      parts.push(s.source.label + " (" + s.source.width + " × " + s.source.height + (s.source.live ? ", live" : "") + ")");
      const live = $("live");
      if (s.source.width && s.source.height) {
        live.setAttribute("width", s.source.width);
        live.setAttribute("height", s.source.height);
      }
    }
    if (s.board) parts.push(s.board.description);
    if (s.file && s.file.path) {
      let f = s.file.path;
      if (!s.file.exists) f += " (not written yet)";
      if (s.file.writable === false) f += " (not writable)";
      parts.push(f);
    } else {
      parts.push("no calibration file: nothing will be saved");
    }
    $("about").textContent = parts.join(" · ");
  }

  function renderError(error) {
    if (!changed("error", error)) return;
    const banner = $("error");
    banner.textContent = error || "";
    banner.hidden = !error;
  }

  function renderDetection(d, board) {
    if (!changed("detection", [d, board])) return;
    const box = $("detection");
    box.replaceChildren();
    if (!d) {
      box.appendChild(el("p", { text: "No detection yet." }));
      return;
    }
    const name = (board && board.point_name) || "point";
    const total = board && board.points ? " of " + board.points : "";
    const verdict = d.found
      ? "Found: " + d.points + total + " " + name + "s" + (d.partial ? " (partly in view)" : "")
      : "Not found";
    box.appendChild(el("p", { className: d.found ? "verdict good" : "verdict bad", text: verdict }));
    if (d.message) box.appendChild(el("p", { className: d.found ? "detail" : "advice", text: d.message }));
    if (!d.found && d.diagnostics) {
      const link = el("a", {
        id: "diagnostics",
        href: "/api/diagnostics.png?t=" + Date.now(),
        target: "_blank",
        rel: "noopener",
        text: "What the search saw (figure)",
      });
      box.appendChild(el("p", {}, [link]));
    }
    box.classList.toggle("found", !!d.found);
  }

  const GOOD = { sharp: "good", good: "good" };

  function renderFocus(f) {
    if (!changed("focus", f)) return;
    const box = $("focus");
    box.replaceChildren();
    if (!f) {
      box.appendChild(el("p", { text: "Measured on the board once it is found." }));
      return;
    }
    const dl = el("dl", { className: "pairs" });
    pairs(dl, [
      ["edge width", num(f.edge_width_px, 2) + " px"],
      ["focus", f.focus || "–", f.focus ? (GOOD[f.focus] ? "good" : "warn") : null],
      ["clipped dark", percent(f.clipped_dark)],
      ["clipped bright", percent(f.clipped_bright)],
      ["exposure", f.exposure || "–", f.exposure ? (GOOD[f.exposure] ? "good" : "warn") : null],
    ]);
    box.appendChild(dl);
    if (f.advice) box.appendChild(el("p", { className: "advice", text: f.advice }));
  }

  function renderPlacements(placements, coverage) {
    const list = placements || [];
    if (changed("placements", list)) {
      const ol = $("placements");
      ol.replaceChildren();
      if (!list.length) {
        ol.appendChild(el("li", { className: "empty", text: "No placements yet." }));
      }
      for (const p of list) {
        const del = el("button", {
          type: "button",
          className: "delete-placement quiet",
          "data-index": p.index,
          "aria-label": "Delete " + p.name,
          text: "Delete",
        });
        del.addEventListener("click", () =>
          act(del, () => request("DELETE", "/api/placements/" + encodeURIComponent(p.index))),
        );
        ol.appendChild(
          el("li", { "data-index": p.index }, [
            el("span", { className: "placement-name", text: p.name }),
            el("span", { className: "hint", text: p.points + " points" }),
            el("a", {
              href: "/api/placements/" + encodeURIComponent(p.index) + ".png",
              target: "_blank",
              rel: "noopener",
              text: "image",
              "aria-label": p.name + ": its image (PNG)",
            }),
            del,
          ]),
        );
      }
    }
    // The map depends on the placements and on the limit it outlines.
    if (changed("coverage-map", [list, coverage ? coverage.limit_mm : null])) {
      const img = $("coverage");
      if (!list.length) {
        img.hidden = true;
        img.removeAttribute("src");
      } else {
        coverageStamp += 1;
        img.src = "/api/coverage.png?v=" + coverageStamp + "-" + Date.now();
      }
    }
    if (changed("coverage-text", coverage)) {
      const cap = $("coverage-text");
      cap.replaceChildren();
      if (coverage && list.length && coverage.sentence) {
        cap.appendChild(el("span", { text: coverage.sentence }));
        if (coverage.advice && coverage.sentence.indexOf(coverage.advice) < 0) {
          cap.appendChild(el("span", { className: "advice block", text: coverage.advice }));
        }
      } else if (coverage && list.length) {
        cap.appendChild(
          el("span", {
            text:
              "Worst predicted error " + num(coverage.worst_mm, 3) + " mm (limit " + num(coverage.limit_mm, 3) + " mm)" +
              (coverage.region ? ", in " + coverage.region : "") + ".",
          }),
        );
        if (coverage.advice) cap.appendChild(el("span", { className: "advice block", text: coverage.advice }));
      }
    }
  }

  function renderCalibration(c, file) {
    if (changed("calibration", c)) {
      const summary = $("summary");
      summary.hidden = !c;
      summary.textContent = c ? c.summary || "" : "";
      const bits = [];
      if (!c) {
        bits.push("Not calibrated yet.");
      } else {
        if (c.placements !== undefined) bits.push(c.placements + " placements");
        if (c.lens_model) bits.push("lens model " + c.lens_model);
        if (c.rms_px !== undefined && c.rms_px !== null) bits.push("rms " + num(c.rms_px, 3) + " px");
        bits.push(c.saved ? "saved" : "not saved yet");
      }
      $("calibration-status").textContent = bits.join(" · ");
    }
    // A new calibration keeps the figures' names: a stamp makes the browser fetch the new ones
    // (and only then: saving changes `saved`, not the figures).
    const figureKey = c ? [c.figures, c.summary, c.rms_px, c.placements, c.lens_model] : null;
    if (changed("figures", figureKey)) {
      const figures = $("figures");
      figures.replaceChildren();
      const stamp = Date.now();
      for (const name of (c && c.figures) || []) {
        const src = "/api/report/" + encodeURIComponent(name) + "?v=" + stamp;
        figures.appendChild(
          el("figure", {}, [
            el("a", { href: src, target: "_blank", rel: "noopener" }, [
              el("img", { src: src, alt: "Report figure " + name, loading: "lazy" }),
            ]),
            el("figcaption", { text: name }),
          ]),
        );
      }
    }
    const ready = downloadable();
    if (changed("downloadable", ready)) {
      const download = $("download");
      download.classList.toggle("unavailable", !ready);
      download.title = ready ? "" : "no calibration yet: Calibrate first";
    }
  }

  // The server serves the saved file, else the calibration made here (saved or not).
  function downloadable() {
    return !!(state && (state.calibration || (state.file && state.file.exists)));
  }

  function renderRegistration(reg) {
    const touches = (reg && reg.touches) || [];
    const fit = reg ? reg.fit : null;
    if (changed("touches", [touches, fit ? fit.outliers : null])) {
      const outliers = new Set((fit && fit.outliers) || []);
      const tbody = $("touches").tBodies[0];
      tbody.replaceChildren();
      if (!touches.length) {
        tbody.appendChild(el("tr", { className: "empty" }, [el("td", { colspan: 5, text: "No touch points yet." })]));
      }
      for (const t of touches) {
        const robot = t.robot || [];
        const del = el("button", {
          type: "button",
          className: "delete-touch quiet",
          "data-id": t.id,
          "aria-label": "Delete touch point " + t.id,
          text: "Delete",
        });
        del.addEventListener("click", () =>
          act(del, () => request("DELETE", "/api/touches/" + encodeURIComponent(t.id))),
        );
        const px = t.image_px ? num(t.image_px[0], 1) + ", " + num(t.image_px[1], 1) : "–";
        tbody.appendChild(
          el("tr", { className: outliers.has(t.id) ? "outlier" : null, "data-id": t.id }, [
            el("td", { text: String(t.id) }),
            el("td", { className: "num", text: robot.map(short).join(", ") }),
            el("td", { className: "num", text: px }),
            el("td", { className: "num", text: num(t.residual_mm, 3) }),
            el("td", {}, [del]),
          ]),
        );
      }
    }
    const regMessage = reg ? reg.message : null;
    if (changed("fit", [fit, regMessage])) {
      const box = $("registration");
      box.replaceChildren();
      if (regMessage) box.appendChild(el("p", { className: "advice", text: regMessage }));
      if (!fit) {
        box.appendChild(el("p", { text: "No fit yet: add touch points." }));
      } else {
        box.appendChild(el("p", { className: "verdict", text: "Quality: " + (fit.quality || "–") }));
        if (fit.outliers && fit.outliers.length) {
          box.appendChild(el("p", { className: "warn", text: "Outliers: " + fit.outliers.join(", ") }));
        }
        if (fit.summary) box.appendChild(el("pre", { className: "summary", text: fit.summary }));
        if (fit.refused) box.appendChild(el("p", { className: "refused", text: "Would not be saved: " + fit.refused }));
      }
    }
  }

  const FRAMES = { robot: "robot", board: "board" };

  function renderParts(watch) {
    if (!changed("watch", watch)) return;
    const frame = watch && watch.frame ? watch.frame : null;
    const parts = (watch && watch.parts) || [];
    $("parts-caption").textContent =
      "Parts in " + (frame ? (FRAMES[frame] || frame) + " coordinates (mm)" : "unknown coordinates") +
      ": " + parts.length;
    const tbody = $("parts").tBodies[0];
    tbody.replaceChildren();
    if (!parts.length) {
      const why = watch && watch.message ? watch.message : "No parts in view.";
      tbody.appendChild(el("tr", { className: "empty" }, [el("td", { colspan: 5, text: why })]));
    } else if (watch && watch.message) {
      tbody.appendChild(el("tr", { className: "empty" }, [el("td", { colspan: 5, text: watch.message })]));
    }
    for (const p of parts) {
      tbody.appendChild(
        el("tr", { "data-id": p.id }, [
          el("td", { text: String(p.id) }),
          el("td", { className: "num", text: num(p.x, 2) }),
          el("td", { className: "num", text: num(p.y, 2) }),
          el("td", { className: "num", text: num(p.angle_deg, 1) }),
          el("td", { className: "num", text: num(p.std_mm, 3) }),
        ]),
      );
    }
  }

  function renderStats(s) {
    if (!changed("stats", s)) return;
    if (!s) {
      $("stats").replaceChildren();
      return;
    }
    pairs($("stats"), [
      ["fps", num(s.fps, 1)],
      ["detect fps", num(s.detect_fps, 1)],
      ["latency", num(s.latency_ms, 0) + " ms"],
      ["frames", String(s.frames)],
      ["dropped", String(s.dropped), s.dropped ? "warn" : null],
    ]);
  }

  function renderSettings(s) {
    // Another browser may change the settings: follow them unless this one is being edited.
    if (!changed("settings", s) || settingsDirty || !s) return;
    fillSettings(s);
  }

  function fillSettings(s) {
    const text = (v) => (v === null || v === undefined ? "" : String(v));
    $("min-area").value = text(s.min_area_px);
    $("max-area").value = text(s.max_area_px);
    $("roi").value = s.roi ? s.roi.join(",") : "";
    $("blur").value = text(s.blur_sigma);
  }

  // ---- the live image ----------------------------------------------------------------------

  const STREAM_FAILED = "the image stream failed (GET /api/stream.mjpg)";
  let imageGeneration = 0; // a new stream or polling loop ends the one before

  // The MJPEG stream in the <img>; if it fails, the frames are polled instead.
  function startStream(fresh) {
    imageGeneration += 1;
    framePolling = false;
    const live = $("live");
    live.onerror = () => startFramePolling(STREAM_FAILED);
    if (fresh) live.src = "/api/stream.mjpg?r=" + Date.now();
  }

  function startFramePolling(reason) {
    if (framePolling) return;
    framePolling = true;
    const generation = ++imageGeneration;
    showMessage(reason + ": showing a new frame every " + FRAME_POLL_MS + " ms instead", "image");
    const live = $("live");
    live.onerror = null;
    let shown = null; // the object URL on screen, released when replaced
    // fetch() rather than an Image: a failure then shows the server's own {"error": ...}.
    const next = async () => {
      if (generation !== imageGeneration) return;
      try {
        const response = await fetch("/api/frame.jpg?t=" + Date.now(), { credentials: "same-origin", cache: "no-store" });
        if (!response.ok) throw new ShownError(await errorText(response, "GET", "/api/frame.jpg"));
        const url = URL.createObjectURL(await response.blob());
        if (generation !== imageGeneration) {
          URL.revokeObjectURL(url);
          return;
        }
        live.src = url;
        if (shown) URL.revokeObjectURL(shown);
        shown = url;
        if (messageSource === "image-poll") clearMessage("image-poll");
        setTimeout(next, FRAME_POLL_MS);
      } catch (err) {
        const text = err instanceof ShownError ? err.message : "GET /api/frame.jpg failed: " + err.message;
        showMessage(text + " (retrying)", "image-poll");
        setTimeout(next, 1000);
      }
    };
    next();
  }

  // The image as large as its column and the window allow, with the frame's aspect.
  function fitLive() {
    const live = $("live");
    const width = live.naturalWidth || (state && state.source ? state.source.width : 0);
    const height = live.naturalHeight || (state && state.source ? state.source.height : 0);
    const column = live.closest(".stage").clientWidth;
    if (!width || !height || !column) return;
    const stacked = window.matchMedia("(max-width: 1000px)").matches;
    const room = stacked ? Infinity : window.innerHeight - document.querySelector(".top").offsetHeight - 72;
    const w = Math.floor(Math.max(160, Math.min(column, (room * width) / height)));
    const h = (w * height) / width; // not rounded: a click maps to the frame's pixels exactly
    if (live.style.width !== w + "px") live.style.width = w + "px";
    if (live.style.height !== h + "px") live.style.height = h + "px";
  }

  function liveImagePoint(event) {
    const live = $("live");
    const rect = live.getBoundingClientRect();
    const width = live.naturalWidth || (state && state.source ? state.source.width : 0);
    const height = live.naturalHeight || (state && state.source ? state.source.height : 0);
    if (!rect.width || !rect.height || !width || !height) return null;
    return {
      x: ((event.clientX - rect.left) * width) / rect.width,
      y: ((event.clientY - rect.top) * height) / rect.height,
    };
  }

  // The picked point's marker, placed in image pixels over the scaled image.
  function placePickMarker() {
    const marker = $("pick-marker");
    const live = $("live");
    const width = live.naturalWidth || (state && state.source ? state.source.width : 0);
    const height = live.naturalHeight || (state && state.source ? state.source.height : 0);
    if (!picked || !picked.image_px || !width || !height || shownMode !== "register") {
      marker.hidden = true;
      return;
    }
    marker.style.left = (100 * picked.image_px[0]) / width + "%";
    marker.style.top = (100 * picked.image_px[1]) / height + "%";
    marker.hidden = false;
  }

  function showPicked(p) {
    picked = p;
    const box = $("picked");
    box.replaceChildren();
    if (!p) {
      box.textContent = "No point picked yet.";
    } else {
      box.appendChild(el("strong", { text: p.name || "point " + p.id }));
      box.appendChild(document.createTextNode(" (id " + p.id + ")"));
      const where = [];
      if (p.board_mm) where.push("board " + num(p.board_mm[0], 2) + ", " + num(p.board_mm[1], 2) + " mm");
      if (p.image_px) where.push("image " + num(p.image_px[0], 1) + ", " + num(p.image_px[1], 1) + " px");
      if (where.length) box.appendChild(el("span", { className: "hint block", text: where.join(" · ") }));
      box.dataset.id = p.id;
    }
    placePickMarker();
  }

  // ---- inputs ------------------------------------------------------------------------------

  // A number from an input: null when empty, an error when not a number.
  function readNumber(input, label) {
    const raw = input.value.trim();
    if (raw === "") {
      if (input.validity && input.validity.badInput) throw new ShownError(label + " is not a number");
      return null;
    }
    const value = Number(raw);
    if (!Number.isFinite(value)) throw new ShownError(label + " is not a number: " + raw);
    return value;
  }

  function readRoi() {
    const raw = $("roi").value.trim();
    if (raw === "") return null;
    const parts = raw.split(/[\s,;]+/).filter((s) => s !== "");
    const values = parts.map(Number);
    if (values.length !== 4 || !values.every(Number.isFinite)) {
      throw new ShownError("the region of interest is four numbers x,y,w,h (or empty for the whole image), not " + raw);
    }
    return values;
  }

  function readSettings() {
    const body = {
      min_area_px: readNumber($("min-area"), "the minimum area"),
      max_area_px: readNumber($("max-area"), "the maximum area"),
      roi: readRoi(),
    };
    const blur = readNumber($("blur"), "the blur sigma");
    if (blur !== null) body.blur_sigma = blur; // empty: the blur stays as it is
    return body;
  }

  async function applySettings() {
    await request("POST", "/api/settings", readSettings());
    settingsDirty = false;
    rendered.settings = undefined; // refill the form from the next state
  }

  // ---- wiring ------------------------------------------------------------------------------

  function wire() {
    for (const m of MODES) {
      const tab = $("tab-" + m);
      tab.addEventListener("click", () =>
        act(tab, async () => {
          await request("POST", "/api/mode", { mode: m });
          renderMode(m);
        }),
      );
    }
    // Arrow keys move between the tabs (the tablist pattern).
    $("tab-setup").parentElement.addEventListener("keydown", (event) => {
      if (event.key !== "ArrowLeft" && event.key !== "ArrowRight") return;
      const i = MODES.indexOf(event.target.dataset.mode);
      if (i < 0) return;
      const j = (i + (event.key === "ArrowRight" ? 1 : MODES.length - 1)) % MODES.length;
      $("tab-" + MODES[j]).focus();
      event.preventDefault();
    });

    $("message-dismiss").addEventListener("click", () => clearMessage());

    const live = $("live");
    startStream(false);
    live.addEventListener("load", () => {
      fitLive();
      placePickMarker();
    });
    // The stream may have failed before this script ran.
    if (live.complete && !live.naturalWidth) startFramePolling(STREAM_FAILED);
    live.addEventListener("click", (event) => {
      if (shownMode !== "register") return;
      const point = liveImagePoint(event);
      if (!point) {
        showMessage("no image yet: wait for the first frame before picking");
        return;
      }
      act(null, async () => {
        const answer = await request("POST", "/api/pick", { x: point.x, y: point.y });
        showPicked(answer);
        // A point touched before: its coordinates to correct (adding replaces it).
        const touches = state && state.registration ? state.registration.touches || [] : [];
        const touched = touches.find((t) => t.id === answer.id);
        const robot = touched && touched.robot ? touched.robot : [];
        ["touch-x", "touch-y", "touch-z"].forEach((id, k) => {
          $(id).value = robot[k] === undefined || robot[k] === null ? "" : String(robot[k]);
        });
        $("touch-x").focus();
      });
    });

    $("capture").addEventListener("click", (e) => act(e.currentTarget, () => request("POST", "/api/capture")));
    $("calibrate").addEventListener("click", (e) =>
      act(e.currentTarget, () => {
        const limit = readNumber($("max-error-mm"), "the error limit");
        if (limit !== null && !(limit > 0)) throw new ShownError("the error limit is a positive number of mm (or empty)");
        return request("POST", "/api/calibrate", { max_error_mm: limit });
      }),
    );
    $("max-error-mm").addEventListener("keydown", (event) => {
      if (event.key === "Enter") $("calibrate").click();
    });
    $("save").addEventListener("click", (e) => act(e.currentTarget, () => request("POST", "/api/save")));

    $("touch-add").addEventListener("click", (e) =>
      act(e.currentTarget, async () => {
        if (!picked) throw new ShownError("pick a point on the image first (Register view: click a dot or corner)");
        const x = readNumber($("touch-x"), "robot x");
        const y = readNumber($("touch-y"), "robot y");
        const z = readNumber($("touch-z"), "robot z");
        if (x === null || y === null) throw new ShownError("type the robot's x and y for " + (picked.name || "the point"));
        const robot = z === null ? [x, y] : [x, y, z];
        await request("POST", "/api/touches", { id: picked.id, robot: robot });
        for (const id of ["touch-x", "touch-y", "touch-z"]) $(id).value = "";
      }),
    );
    for (const id of ["touch-x", "touch-y", "touch-z"]) {
      $(id).addEventListener("keydown", (event) => {
        if (event.key === "Enter") $("touch-add").click();
      });
    }

    const upload = $("touches-upload");
    upload.addEventListener("change", () => {
      const file = upload.files && upload.files[0];
      if (!file) return;
      act(null, async () => {
        try {
          const text = await file.text();
          await request("PUT", "/api/touches.csv", text, "text/csv");
        } finally {
          upload.value = ""; // the same file can be chosen again
        }
      });
    });

    $("register").addEventListener("click", (e) =>
      act(e.currentTarget, () => request("POST", "/api/register", { force: $("force").checked })),
    );

    const form = $("settings-form");
    for (const id of ["min-area", "max-area", "roi", "blur"]) {
      $(id).addEventListener("input", () => {
        settingsDirty = true;
      });
    }
    form.addEventListener("submit", (event) => {
      event.preventDefault();
      act($("apply-settings"), applySettings);
    });
    // Saving what the form shows: edits not yet applied are applied first.
    $("save-settings").addEventListener("click", (e) =>
      act(e.currentTarget, async () => {
        if (settingsDirty) await applySettings();
        await request("POST", "/api/settings/save");
      }),
    );

    // With nothing to download the link would save an error: say why instead.
    $("download").addEventListener("click", (event) => {
      if (downloadable()) return;
      event.preventDefault();
      clearMessage();
      showMessage("no calibration yet: capture placements and Calibrate first");
    });

    const coverage = $("coverage");
    coverage.addEventListener("load", () => {
      coverage.hidden = false;
    });
    coverage.addEventListener("error", () => {
      coverage.hidden = true; // 404 before the first capture, or while it is being computed
    });

    window.addEventListener("resize", fitLive);
  }

  wire();
  poll();
})();
