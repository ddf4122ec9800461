// softcbf view: draws the runs of a `softcbf simulate` directory in 3-D from the data the
// page embeds (#softcbf-view-data; its format is runtime/src/view/data.rs). A perspective
// camera on a 2-D canvas, the painter's algorithm (far to near), no library, nothing
// fetched. The page reports its state in <body data-status> ("ok" or "error"), data-frame,
// data-time and data-views (where each view's canvas is), in #status and in the document's
// title, for people and for tests (.ci/browser-view).
"use strict";
(function () {
  const body = document.body;
  const statusLine = document.getElementById("status");
  let failed = false;

  function fail(message) {
    failed = true;
    body.dataset.status = "error";
    statusLine.className = "error";
    statusLine.textContent = "error: " + message;
    document.title = "softcbf view: error";
  }
  window.addEventListener("error", (event) => fail(event.message || "a script error"));
  window.addEventListener("unhandledrejection", (event) => fail(String(event.reason)));
  const consoleError = console.error.bind(console);
  console.error = (...args) => {
    fail(args.map(String).join(" "));
    consoleError(...args);
  };

  let data;
  try {
    data = JSON.parse(document.getElementById("softcbf-view-data").textContent);
  } catch (error) {
    fail("the embedded data cannot be read: " + error.message);
    return;
  }
  if (data.format !== 1) {
    fail("the embedded data is of format " + data.format + ", this page reads format 1");
    return;
  }
  if (!data.runs.length || !data.times.length) {
    fail("the embedded data has no run or no frame");
    return;
  }

  // ---- numbers and vectors ------------------------------------------------------------
  const DEG = Math.PI / 180;
  const FOV = 30 * DEG;
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const point = (flat, k) => [flat[3 * k], flat[3 * k + 1], flat[3 * k + 2]];
  const points = (flat) => {
    const out = [];
    for (let k = 0; 3 * k + 2 < flat.length; k++) out.push(point(flat, k));
    return out;
  };
  const colour = {};
  for (const [name, hex] of data.colours) colour[name] = hex;
  const RUN_COLOURS = ["#2166ac", "#b2182b", "#1b7837", "#762a83"];

  function niceStep(span) {
    const unit = Math.pow(10, Math.floor(Math.log10(span)));
    for (const m of [1, 2, 5, 10]) if (m * unit >= span) return m * unit;
    return 10 * unit;
  }
  function seconds(t) {
    if (t === null || !isFinite(t)) return "–";
    let text = t.toFixed(3);
    text = text.replace(/0+$/, "").replace(/\.$/, "");
    return text.replace("-", "−") + " s";
  }
  function barrierText(value, unit) {
    if (value === null || value === undefined) return "not finite";
    if (unit === "rad") return (value >= 0 ? "+" : "−") + Math.abs(value).toFixed(3) + " rad";
    const mm = 1000 * value;
    if (Math.abs(mm) < 0.005) return "0.00 mm";
    return (mm >= 0 ? "+" : "−") + Math.abs(mm).toFixed(2) + " mm";
  }

  // ---- barrier colours: red past the tolerance below zero, orange near the margin, a
  // scale above (square root, so that the last millimetres get most of it) ---------------
  const RAMP = [
    [0.0, [240, 200, 40]],
    [0.5, [60, 170, 90]],
    [1.0, [35, 100, 175]],
  ];
  function ramp(u) {
    for (let k = 1; k < RAMP.length; k++) {
      const [u1, c1] = RAMP[k];
      const [u0, c0] = RAMP[k - 1];
      if (u <= u1) {
        const s = (u - u0) / (u1 - u0);
        const c = c0.map((x, i) => Math.round(x + s * (c1[i] - x)));
        return "rgb(" + c.join(",") + ")";
      }
    }
    return "rgb(" + RAMP[RAMP.length - 1][1].join(",") + ")";
  }
  function scalePosition(b) {
    const span = data.colour_top - data.active_below;
    return Math.sqrt(Math.min(1, Math.max(0, (b - data.active_below) / span)));
  }
  function barrierColour(b) {
    if (b === null || b === undefined) return colour.muted;
    if (b < -data.tolerance) return colour.violated;
    if (b <= data.active_below) return colour.active;
    return ramp(scalePosition(b));
  }

  // ---- the camera ---------------------------------------------------------------------
  const low = data.bounds[0];
  const high = data.bounds[1];
  const centre = [0, 1, 2].map((k) => 0.5 * (low[k] + high[k]));
  const radius = 0.5 * Math.hypot(high[0] - low[0], high[1] - low[1], high[2] - low[2]) || 0.1;
  const home = {
    az: data.camera.azimuth_deg,
    el: data.camera.elevation_deg,
    zoom: 1.7,
    target: centre.slice(),
  };
  let camera = { ...home, target: home.target.slice() };

  // Looking from azimuth `az` and elevation `el` (as the 3-D figure's camera), from a
  // distance at which the scene box's sphere fills the view at zoom 1 (the robot, inside
  // it, fills most of it at the starting zoom).
  function projector(width, height) {
    const a = camera.az * DEG;
    const e = camera.el * DEG;
    const [sa, ca, se, ce] = [Math.sin(a), Math.cos(a), Math.sin(e), Math.cos(e)];
    const right = [-sa, ca, 0];
    const up = [-se * ca, -se * sa, ce];
    const toward = [ce * ca, ce * sa, se];
    const distance = radius / Math.sin(FOV / 2) / camera.zoom;
    const eye = add(camera.target, scale(toward, distance));
    const focal = (0.5 * Math.min(width, height)) / Math.tan(FOV / 2);
    const near = 0.02 * radius;
    const view = (p) => {
      const v = sub(p, eye);
      return [dot(v, right), dot(v, up), -dot(v, toward)];
    };
    const screen = (c) => ({
      x: width / 2 + (focal * c[0]) / c[2],
      y: height / 2 - (focal * c[1]) / c[2],
      z: c[2],
      s: focal / c[2],
    });
    return {
      right,
      up,
      distance,
      focal,
      // A point on screen with its depth and pixels per metre, or null behind the camera.
      project(p) {
        const c = view(p);
        return c[2] < near ? null : screen(c);
      },
      // A segment cut at the near plane, or null when all of it is behind the camera.
      segment(p, q) {
        let a = view(p);
        let b = view(q);
        if (a[2] < near && b[2] < near) return null;
        if (a[2] < near || b[2] < near) {
          const s = (near - a[2]) / (b[2] - a[2]);
          const cut = [0, 1, 2].map((k) => a[k] + s * (b[k] - a[k]));
          if (a[2] < near) a = cut;
          else b = cut;
        }
        return [screen(a), screen(b)];
      },
    };
  }

  // ---- drawing --------------------------------------------------------------------------
  function line(ctx, a, b, style, width, dash) {
    ctx.strokeStyle = style;
    ctx.lineWidth = width;
    ctx.setLineDash(dash || []);
    ctx.beginPath();
    ctx.moveTo(a.x, a.y);
    ctx.lineTo(b.x, b.y);
    ctx.stroke();
    ctx.setLineDash([]);
  }
  function polygon(ctx, corners, fill, alpha, edge, width) {
    ctx.beginPath();
    corners.forEach((c, k) => (k ? ctx.lineTo(c.x, c.y) : ctx.moveTo(c.x, c.y)));
    ctx.closePath();
    ctx.globalAlpha = alpha;
    ctx.fillStyle = fill;
    ctx.fill();
    ctx.globalAlpha = 1;
    if (edge) {
      ctx.strokeStyle = edge;
      ctx.lineWidth = width;
      ctx.stroke();
    }
  }
  function disc(ctx, at, r, fill, edge, width) {
    ctx.beginPath();
    ctx.arc(at.x, at.y, r, 0, 2 * Math.PI);
    ctx.fillStyle = fill;
    ctx.fill();
    if (edge) {
      ctx.strokeStyle = edge;
      ctx.lineWidth = width || 1;
      ctx.stroke();
    }
  }

  // The floor (the base plate's plane, z = 0) as a grid over the scene, and the axes.
  function drawFloor(ctx, P) {
    const step = niceStep(Math.max(high[0] - low[0], high[1] - low[1]) / 6);
    const x0 = Math.floor(low[0] / step) * step;
    const x1 = Math.ceil(high[0] / step) * step;
    const y0 = Math.floor(low[1] / step) * step;
    const y1 = Math.ceil(high[1] / step) * step;
    for (let x = x0; x <= x1 + 1e-9; x += step) {
      const s = P.segment([x, y0, 0], [x, y1, 0]);
      if (s) line(ctx, s[0], s[1], "#e4e4e4", 1);
    }
    for (let y = y0; y <= y1 + 1e-9; y += step) {
      const s = P.segment([x0, y, 0], [x1, y, 0]);
      if (s) line(ctx, s[0], s[1], "#e4e4e4", 1);
    }
    const axes = [
      ["x", [step, 0, 0], "#c0392b"],
      ["y", [0, step, 0], "#27ae60"],
      ["z", [0, 0, step], "#2c5aa0"],
    ];
    ctx.font = "12px sans-serif";
    for (const [name, end, style] of axes) {
      const s = P.segment([0, 0, 0], end);
      if (!s) continue;
      line(ctx, s[0], s[1], style, 1.5);
      ctx.fillStyle = style;
      ctx.fillText(name, s[1].x + 3, s[1].y - 3);
    }
    return step;
  }

  function drawSphere(ctx, P, obstacle) {
    const c = P.project(obstacle.centre);
    if (!c) return;
    const r = obstacle.radius * c.s;
    const gradient = ctx.createRadialGradient(c.x - 0.35 * r, c.y - 0.35 * r, 0.1 * r, c.x, c.y, r);
    gradient.addColorStop(0, "#ffffff");
    gradient.addColorStop(1, colour.sphere_fill);
    ctx.globalAlpha = 0.55;
    disc(ctx, c, r, gradient, null);
    ctx.globalAlpha = 1;
    ctx.strokeStyle = colour.sphere_edge;
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    ctx.arc(c.x, c.y, r, 0, 2 * Math.PI);
    ctx.stroke();
    if (obstacle.margin > 0) {
      ctx.setLineDash([5, 4]);
      ctx.beginPath();
      ctx.arc(c.x, c.y, (obstacle.radius + obstacle.margin) * c.s, 0, 2 * Math.PI);
      ctx.stroke();
      ctx.setLineDash([]);
    }
  }

  function drawArrow(ctx, P, from, direction, length, style) {
    const s = P.segment(from, add(from, scale(direction, length)));
    if (!s) return;
    line(ctx, s[0], s[1], style, 2);
    const angle = Math.atan2(s[1].y - s[0].y, s[1].x - s[0].x);
    ctx.fillStyle = style;
    ctx.beginPath();
    ctx.moveTo(s[1].x, s[1].y);
    ctx.lineTo(s[1].x - 9 * Math.cos(angle - 0.4), s[1].y - 9 * Math.sin(angle - 0.4));
    ctx.lineTo(s[1].x - 9 * Math.cos(angle + 0.4), s[1].y - 9 * Math.sin(angle + 0.4));
    ctx.closePath();
    ctx.fill();
  }

  // One run at one frame, as the 3-D figure draws it: half-space patches behind, then
  // plates, backbone and tendon pieces and spheres far to near, then the marks on top.
  function drawRun(view, frame) {
    const ctx = view.ctx;
    const ratio = window.devicePixelRatio || 1;
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, view.width, view.height);
    const P = projector(view.width, view.height);
    const step = drawFloor(ctx, P);
    for (const obstacle of data.obstacles) {
      if (obstacle.kind !== "half_space") continue;
      const corners = points(obstacle.patch).map(P.project);
      if (corners.length >= 3 && corners.every(Boolean)) {
        polygon(ctx, corners, colour.wall_fill, 0.22, colour.wall_edge, 1);
      }
    }
    const pieces = [];
    const robot = frame.robot;
    if (robot) {
      robot.plates.forEach((plate, k) => {
        const corners = points(plate).map(P.project);
        if (corners.length < 3 || !corners.every(Boolean)) return;
        const depth = corners.reduce((sum, c) => sum + c.z, 0) / corners.length;
        const base = k === 0;
        pieces.push([depth, () => polygon(ctx, corners, base ? colour.base_fill : colour.plate_fill,
          1, base ? colour.base_edge : colour.plate_edge, 2)]);
      });
      const lines = (flat, style, width) => {
        const pts = points(flat);
        for (let k = 1; k < pts.length; k++) {
          const s = P.segment(pts[k - 1], pts[k]);
          if (s) pieces.push([0.5 * (s[0].z + s[1].z), () => line(ctx, s[0], s[1], style, width)]);
        }
      };
      robot.backbones.forEach((b) => lines(b, colour.backbone, 3));
      robot.tendons.forEach((t) => lines(t, colour.tendon, 1.4));
    }
    for (const obstacle of data.obstacles) {
      if (obstacle.kind !== "sphere") continue;
      const c = P.project(obstacle.centre);
      if (c) pieces.push([c.z, () => drawSphere(ctx, P, obstacle)]);
    }
    pieces.sort((a, b) => b[0] - a[0]);
    for (const [, draw] of pieces) draw();
    for (const obstacle of data.obstacles) {
      if (obstacle.kind !== "half_space" || obstacle.patch.length < 9) continue;
      const pts = points(obstacle.patch);
      const middle = scale(pts.reduce(add, [0, 0, 0]), 1 / pts.length);
      drawArrow(ctx, P, middle, obstacle.normal, data.arrow, colour.wall_edge);
    }
    if (robot) drawMarks(ctx, P, frame, robot);
    // A scale bar of the floor grid's step.
    ctx.fillStyle = colour.muted;
    ctx.font = "12px sans-serif";
    ctx.fillText("grid " + Math.round(step * 1000) + " mm", 8, view.height - 8);
  }

  // Corners and watched points, coloured by their barrier; those at most `active_below`
  // get a dashed line to the plate below (a corner) or to their obstacle (a watched point).
  function drawMarks(ctx, P, frame, robot) {
    const marks = [];
    const valid = !frame.invalid;
    data.corners.forEach((corner, k) => {
      const at = P.project(point(robot.corners, 2 * k));
      const foot = P.project(point(robot.corners, 2 * k + 1));
      if (at) marks.push({ at, to: foot, b: frame.b[corner.barrier], corner: true, arc: false });
    });
    data.watched.forEach((watched, k) => {
      const at = P.project(point(robot.watched, 2 * k));
      const to = P.project(point(robot.watched, 2 * k + 1));
      if (at) marks.push({ at, to, b: frame.b[watched.barrier], corner: false, arc: watched.arc });
    });
    marks.sort((a, b) => b.at.z - a.at.z);
    for (const mark of marks) {
      const b = valid ? mark.b : null;
      const fill = barrierColour(b);
      const active = b !== null && b <= data.active_below;
      if (active && mark.to) {
        line(ctx, mark.at, mark.to, fill, 2, [5, 3]);
        disc(ctx, mark.to, 2, fill, null);
      }
      if (mark.corner) {
        disc(ctx, mark.at, active ? 6.5 : 4.5, fill, "#000000", 1);
      } else {
        disc(ctx, mark.at, active ? 5.5 : 3.5, fill, mark.arc ? "#ffffff" : "#000000", 1.2);
      }
    }
  }

  // ---- the page -------------------------------------------------------------------------
  const frames = data.times.length;
  const views = [];
  const viewsElement = document.getElementById("views");
  data.runs.forEach((run, k) => {
    const element = document.createElement("div");
    element.className = "run";
    const heading = document.createElement("h2");
    heading.textContent = run.title;
    heading.style.color = RUN_COLOURS[k % RUN_COLOURS.length];
    heading.title = run.file;
    const canvas = document.createElement("canvas");
    const caption = document.createElement("div");
    caption.className = "caption";
    element.append(heading, canvas, caption);
    viewsElement.append(element);
    views.push({ run, canvas, caption, ctx: canvas.getContext("2d"), width: 0, height: 0 });
  });
  document.getElementById("heading").textContent = "softcbf view: " + data.title;
  const rate = Number(data.fps.toPrecision(4));
  document.getElementById("meta").textContent =
    data.robot + " · " + data.runs.length + (data.runs.length === 1 ? " run · " : " runs side by side · ") +
    frames + " frames, " + rate + " per second of robot time (each the record's row nearest to its time), " +
    seconds(data.times[0]) + " to " + seconds(data.times[frames - 1]) + " · written by " + data.softcbf;

  const slider = document.getElementById("slider");
  const timeLabel = document.getElementById("time");
  const playButton = document.getElementById("play");
  const speedSelect = document.getElementById("speed");
  const loopBox = document.getElementById("loop");
  const strip = document.getElementById("strip");
  slider.max = String(frames - 1);
  let current = 0;

  function caption(view, frame) {
    const parts = ["t = " + seconds(frame.t)];
    let second;
    if (!frame.robot) {
      second = '<span class="invalid">no finite state in the record</span>';
    } else if (frame.invalid) {
      second = '<span class="invalid">invalid state:</span> ' + escapeHtml(frame.invalid);
    } else {
      let lowest = -1;
      frame.b.forEach((b, j) => {
        if (b !== null && (lowest < 0 || b < frame.b[lowest])) lowest = j;
      });
      if (lowest < 0) {
        second = "no barrier";
      } else {
        const b = frame.b[lowest];
        const info = data.barriers[lowest];
        const kind = b < -data.tolerance ? "violated" : b <= data.active_below ? "active" : "";
        second = "lowest b = <span class=\"" + kind + "\">" + barrierText(b, info.unit) +
          "</span> (" + escapeHtml(info.label) + ")";
      }
    }
    view.caption.innerHTML = escapeHtml(parts.join(" ")) + "<br>" + second;
  }
  function escapeHtml(text) {
    return String(text).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);
  }

  function drawAll() {
    for (const view of views) drawRun(view, view.run.frames[current]);
    drawStrip();
  }
  function setFrame(k) {
    current = Math.max(0, Math.min(frames - 1, k));
    slider.value = String(current);
    timeLabel.textContent = "t = " + seconds(data.times[current]) + " · frame " + (current + 1) + " of " + frames;
    for (const view of views) caption(view, view.run.frames[current]);
    body.dataset.frame = String(current);
    body.dataset.time = String(data.times[current]);
    drawAll();
  }
  function nearestFrame(t) {
    let best = 0;
    data.times.forEach((s, k) => {
      if (Math.abs(s - t) < Math.abs(data.times[best] - t)) best = k;
    });
    return best;
  }

  // Keeps a drag's pointer events on the element that it started on, where the browser
  // knows the pointer (an event made by a script has none to capture).
  function capture(element, pointer) {
    try {
      element.setPointerCapture(pointer);
    } catch (error) {
      if (!(error instanceof DOMException)) throw error;
    }
  }

  // ---- the lowest barrier over time (barriers in metres), one line per run --------------
  const lowestSeries = data.runs.map((run) =>
    run.frames.map((frame) => {
      if (frame.invalid || !frame.robot) return null;
      let lowest = null;
      frame.b.forEach((b, j) => {
        if (b !== null && data.barriers[j].unit === "m" && (lowest === null || b < lowest)) lowest = b;
      });
      return lowest;
    }),
  );
  const stripBox = { left: 48, right: 12, top: 8, bottom: 20 };
  function drawStrip() {
    const ratio = window.devicePixelRatio || 1;
    const width = strip.clientWidth;
    const height = strip.clientHeight;
    if (strip.width !== Math.round(width * ratio)) strip.width = Math.round(width * ratio);
    if (strip.height !== Math.round(height * ratio)) strip.height = Math.round(height * ratio);
    const ctx = strip.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, width, height);
    // A symmetric logarithmic axis: linear within ±0.1 mm, logarithmic beyond, so that
    // both the last tenth of a millimetre and centimetres of travel show.
    const warp = (mm) => Math.sign(mm) * Math.log10(1 + Math.abs(mm) / 0.1);
    const values = lowestSeries.flat().filter((v) => v !== null).map((v) => 1000 * v);
    let lo = warp(Math.min(-0.1, ...values));
    let hi = warp(Math.max(0.1, ...values));
    const pad = 0.06 * (hi - lo);
    lo -= pad;
    hi += pad;
    const { left, right, top, bottom } = stripBox;
    const t0 = data.times[0];
    const t1 = data.times[frames - 1];
    const x = (t) => left + ((t - t0) / (t1 - t0 || 1)) * (width - left - right);
    const y = (mm) => top + ((hi - warp(mm)) / (hi - lo)) * (height - top - bottom);
    ctx.font = "11px sans-serif";
    ctx.fillStyle = colour.muted;
    ctx.textAlign = "right";
    for (const mm of [-1000, -100, -10, -1, 0, 1, 10, 100, 1000]) {
      const w = warp(mm);
      if (w < lo || w > hi) continue;
      ctx.fillText(String(mm).replace("-", "−"), left - 6, y(mm) + 4);
      line(ctx, { x: left, y: y(mm) }, { x: width - right, y: y(mm) }, mm ? "#eeeeee" : "#999999", 1,
        mm ? [] : [4, 3]);
    }
    ctx.textAlign = "left";
    ctx.fillText(seconds(t0), left, height - 5);
    ctx.fillText("lowest barrier b [mm] of each run (barriers in metres), click to go to a time",
      left + 70, height - 5);
    ctx.textAlign = "right";
    ctx.fillText(seconds(t1), width - right, height - 5);
    ctx.textAlign = "left";
    lowestSeries.forEach((series, k) => {
      ctx.strokeStyle = RUN_COLOURS[k % RUN_COLOURS.length];
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      let open = false;
      series.forEach((v, i) => {
        if (v === null) {
          open = false;
          return;
        }
        const px = x(data.times[i]);
        const py = y(1000 * v);
        if (open) ctx.lineTo(px, py);
        else ctx.moveTo(px, py);
        open = true;
      });
      ctx.stroke();
    });
    const now = x(data.times[current]);
    line(ctx, { x: now, y: top }, { x: now, y: height - bottom }, "#141414", 1);
  }
  function seekStrip(event) {
    const rect = strip.getBoundingClientRect();
    const { left, right } = stripBox;
    const u = (event.clientX - rect.left - left) / (rect.width - left - right);
    const t0 = data.times[0];
    const t1 = data.times[frames - 1];
    setFrame(nearestFrame(t0 + Math.max(0, Math.min(1, u)) * (t1 - t0)));
  }
  let stripDragging = false;
  strip.addEventListener("pointerdown", (event) => {
    stripDragging = true;
    capture(event.target, event.pointerId);
    stop();
    seekStrip(event);
  });
  strip.addEventListener("pointermove", (event) => stripDragging && seekStrip(event));
  strip.addEventListener("pointerup", () => (stripDragging = false));
  strip.addEventListener("pointercancel", () => (stripDragging = false));

  // ---- the legend -------------------------------------------------------------------------
  function drawLegend() {
    const canvas = document.getElementById("scale");
    const ratio = window.devicePixelRatio || 1;
    const width = canvas.clientWidth;
    const height = canvas.clientHeight;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(height * ratio);
    const ctx = canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.clearRect(0, 0, width, height);
    const [x0, x1, y0, bar] = [84, width - 14, 6, 12];
    ctx.fillStyle = colour.violated;
    ctx.fillRect(6, y0, 34, bar);
    ctx.fillStyle = colour.active;
    ctx.fillRect(44, y0, 34, bar);
    for (let px = x0; px < x1; px++) {
      ctx.fillStyle = ramp((px - x0) / (x1 - x0));
      ctx.fillRect(px, y0, 1, bar);
    }
    ctx.fillStyle = colour.muted;
    ctx.font = "11px sans-serif";
    ctx.textAlign = "center";
    ctx.fillText("< 0", 23, y0 + bar + 13);
    ctx.fillText("≤ " + 1000 * data.active_below, 61, y0 + bar + 13);
    const top = 1000 * data.colour_top;
    for (const mm of [1, 2, 5, 10, 20, 50, 100, 200, 500]) {
      if (mm <= 1000 * data.active_below || mm > top * (1 + 1e-9)) continue;
      const px = x0 + scalePosition(mm / 1000) * (x1 - x0);
      ctx.fillText((mm === top ? "≥ " : "") + mm, px, y0 + bar + 13);
    }
    ctx.textAlign = "left";
    ctx.fillText("corner and watched-point barriers b [mm]", 6, y0 + bar + 27);
    const parts = [
      "red: b below −" + Number((1e6 * data.tolerance).toPrecision(3)) +
        " µm (past its margin); orange: b ≤ " + 1000 * data.active_below +
        " mm, dashed to the plate below or to the obstacle",
    ];
    if (data.obstacles.some((o) => o.kind === "sphere")) parts.push("purple: spheres (dashed: + margin ε)");
    if (data.obstacles.some((o) => o.kind === "half_space")) parts.push("green: half-spaces (arrow: the allowed side)");
    if (data.watched.length) parts.push("small dots: watched points");
    document.getElementById("legend-text").textContent = parts.join(" · ");
  }

  // ---- sizes ------------------------------------------------------------------------------
  function layout() {
    const ratio = window.devicePixelRatio || 1;
    for (const view of views) {
      const width = Math.max(200, view.canvas.clientWidth || 400);
      const height = Math.round(Math.max(280, Math.min(0.8 * width, window.innerHeight - 330, 680)));
      view.width = width;
      view.height = height;
      view.canvas.style.height = height + "px";
      view.canvas.width = Math.round(width * ratio);
      view.canvas.height = Math.round(height * ratio);
    }
    drawLegend();
  }

  // ---- the mouse ----------------------------------------------------------------------------
  let drag = null;
  for (const view of views) {
    const canvas = view.canvas;
    canvas.addEventListener("pointerdown", (event) => {
      drag = {
        x: event.clientX,
        y: event.clientY,
        pan: event.shiftKey || event.button === 1 || event.button === 2,
        view,
      };
      capture(event.target, event.pointerId);
      canvas.classList.add("dragging");
      event.preventDefault();
    });
    canvas.addEventListener("pointermove", (event) => {
      if (!drag) return;
      const dx = event.clientX - drag.x;
      const dy = event.clientY - drag.y;
      drag.x = event.clientX;
      drag.y = event.clientY;
      if (drag.pan) {
        const P = projector(drag.view.width, drag.view.height);
        const metres = P.distance / P.focal;
        camera.target = add(camera.target, add(scale(P.right, -dx * metres), scale(P.up, dy * metres)));
      } else {
        camera.az -= 0.4 * dx;
        camera.el = Math.max(-89, Math.min(89, camera.el + 0.4 * dy));
      }
      drawAll();
    });
    const release = () => {
      drag = null;
      canvas.classList.remove("dragging");
    };
    canvas.addEventListener("pointerup", release);
    canvas.addEventListener("pointercancel", release);
    canvas.addEventListener("contextmenu", (event) => event.preventDefault());
    canvas.addEventListener("wheel", (event) => {
      event.preventDefault();
      camera.zoom = Math.max(0.2, Math.min(40, camera.zoom * Math.exp(-0.0015 * event.deltaY)));
      drawAll();
    }, { passive: false });
    canvas.addEventListener("dblclick", resetCamera);
  }
  function resetCamera() {
    camera = { ...home, target: home.target.slice() };
    drawAll();
  }
  document.getElementById("reset").addEventListener("click", resetCamera);

  // ---- playing ------------------------------------------------------------------------------
  let playing = false;
  let playTime = 0;
  let lastNow = 0;
  function stop() {
    playing = false;
    playButton.textContent = "▶ play";
  }
  // Playback runs on a timer of about 60 Hz (not on animation frames, which a headless
  // browser's virtual time does not advance), drawing only when the frame changes.
  const TICK_MS = 16;
  function play() {
    if (current >= frames - 1) setFrame(0);
    playing = true;
    playTime = data.times[current];
    lastNow = performance.now();
    playButton.textContent = "❚❚ pause";
    setTimeout(advance, TICK_MS);
  }
  function advance() {
    if (!playing) return;
    const now = performance.now();
    playTime += ((now - lastNow) / 1000) * Number(speedSelect.value);
    lastNow = now;
    const end = data.times[frames - 1];
    if (playTime > end) {
      if (loopBox.checked && frames > 1) {
        playTime = data.times[0];
      } else {
        setFrame(frames - 1);
        stop();
        return;
      }
    }
    let k = current;
    while (k + 1 < frames && data.times[k + 1] <= playTime) k++;
    if (data.times[k] > playTime) k = nearestFrame(playTime);
    if (k !== current) setFrame(k);
    setTimeout(advance, TICK_MS);
  }
  playButton.addEventListener("click", () => (playing ? stop() : play()));
  slider.addEventListener("input", () => {
    stop();
    setFrame(Number(slider.value));
  });
  document.addEventListener("keydown", (event) => {
    // A focused control handles its own keys.
    if (event.target instanceof Element && event.target.closest("input, select, button")) return;
    if (event.key === "ArrowRight") setFrame(current + 1);
    else if (event.key === "ArrowLeft") setFrame(current - 1);
    else if (event.key === " ") playing ? stop() : play();
    else if (event.key === "r") resetCamera();
    else return;
    event.preventDefault();
  });

  // ---- the address: #t=SECONDS&az=DEG&el=DEG&zoom=F ------------------------------------------
  function readAddress() {
    const fields = {};
    for (const part of window.location.hash.replace(/^#/, "").split("&")) {
      const [key, value] = part.split("=");
      const number = Number(value);
      if (key && value !== undefined && value !== "" && isFinite(number)) fields[key] = number;
    }
    if ("az" in fields) camera.az = fields.az;
    if ("el" in fields) camera.el = Math.max(-89, Math.min(89, fields.el));
    if ("zoom" in fields && fields.zoom > 0) camera.zoom = Math.max(0.2, Math.min(40, fields.zoom));
    return "t" in fields ? nearestFrame(fields.t) : current;
  }
  window.addEventListener("hashchange", () => setFrame(readAddress()));
  window.addEventListener("resize", () => {
    layout();
    drawAll();
  });

  layout();
  setFrame(readAddress());
  // Where each view is on the page, `x,y,width,height` in CSS pixels, `;` between views.
  body.dataset.views = views
    .map((view) => {
      const rect = view.canvas.getBoundingClientRect();
      return [rect.left + window.scrollX, rect.top + window.scrollY, rect.width, rect.height]
        .map(Math.round)
        .join(",");
    })
    .join(";");
  if (!failed) {
    body.dataset.status = "ok";
    statusLine.textContent = "ready: " + data.runs.length + " run(s), " + frames + " frames";
    document.title = "softcbf view: " + data.title;
  }
})();
