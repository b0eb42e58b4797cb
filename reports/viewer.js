// The report page's image viewer: for each scene, any two of its images (input, reference, every
// method and variant, their FLIP, HDR-FLIP and relMSE maps) in a split view with a draggable
// handle, a second view beside it, zoom (wheel) and pan (drag) shared by every view of the
// scene, a pixel loupe with both sides' linear values, keyboard shortcuts as in tev and JERI,
// exposure and tone mapping applied to the linear radiance, colour bars for the error maps, and
// the crops with each method's error there. A sequence's frames (rows name.f00, name.f01, ...)
// share one viewer with a frame slider: another frame shows the same two images (by method and
// kind) of that frame, with the zoom, split and exposure kept.
//
// Written here rather than vendored: the maintained comparison components (img-comparison-slider,
// JERI) show 8-bit images or fetch EXRs over XHR, which a page opened from file:// may not do;
// this viewer reads the half floats that reports/viewer.py writes as script files
// (web/viewer/manifest.js, web/viewer/s<i>/<j>.js), which load from disk without a server.
"use strict";

var DNB = (function () {
  var pending = {};  // image id -> [resolve, reject]
  var loaded = {};   // image id -> {w, h, c, data: Float32Array}
  var halfLut = null;

  function halfToFloatTable() {
    var t = new Float32Array(65536);
    for (var i = 0; i < 65536; i++) {
      var s = i & 0x8000 ? -1 : 1, e = (i >> 10) & 0x1f, m = i & 0x3ff;
      t[i] = e === 0 ? s * m * Math.pow(2, -24) : e === 31 ? (m ? NaN : s * Infinity) : s * (1 + m / 1024) * Math.pow(2, e - 15);
    }
    return t;
  }

  // Called by each image's script file.
  // Called by each image's script file: "deflate" data is zlib-compressed little-endian halves.
  function image(id, w, h, c, encoding, b64) {
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    var raw = encoding === "deflate"
      ? new Response(new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"))).arrayBuffer()
      : Promise.resolve(bytes.buffer);
    raw.then(function (buf) {
      if (!halfLut) halfLut = halfToFloatTable();
      var halves = new Uint16Array(buf), data = new Float32Array(halves.length);
      if (halves.length !== w * h * c) throw new Error(id + ": " + halves.length + " values, expected " + w * h * c);
      for (var k = 0; k < halves.length; k++) data[k] = halfLut[halves[k]];
      loaded[id] = {w: w, h: h, c: c, data: data};
      if (pending[id]) { pending[id][0](loaded[id]); delete pending[id]; }
    }).catch(function (e) {
      console.error("cannot decode image " + id + ": " + e);
      if (pending[id]) { pending[id][1](e); delete pending[id]; }
    });
  }

  function load(entry) {
    if (loaded[entry.id]) return Promise.resolve(loaded[entry.id]);
    return new Promise(function (resolve, reject) {
      if (pending[entry.id]) {
        var prev = pending[entry.id];
        pending[entry.id] = [function (v) { prev[0](v); resolve(v); }, function (e) { prev[1](e); reject(e); }];
        return;
      }
      pending[entry.id] = [resolve, reject];
      var s = document.createElement("script");
      s.src = entry.file;
      s.onerror = function () {
        console.error("cannot load " + entry.file);
        reject(new Error(entry.file));
      };
      document.head.appendChild(s);
    });
  }
  return {image: image, load: load};
})();

(function () {
  if (typeof DNB_MANIFEST === "undefined") {
    console.error("web/viewer/manifest.js did not load");
    return;
  }
  var M = DNB_MANIFEST;
  var scenes = [];
  var active = null;  // the scene the keyboard drives: the last one hovered or focused

  // ---------------------------------------------------------------------------------------------
  // Tone mapping and colour maps

  function srgb(v) {  // linear [0,1] -> sRGB 8-bit
    v = v <= 0 ? 0 : v >= 1 ? 1 : v;
    return Math.round(255 * (v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055));
  }
  // Narkowicz's fit of the ACES filmic curve (the paper's tone mapper, metrics/ hdrflip).
  function aces(x) { return (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14); }

  function errorIndex(v, scale) {
    var t;
    if (scale.log) t = (Math.log10(Math.max(v, 1e-30)) - Math.log10(scale.min)) / (Math.log10(scale.max) - Math.log10(scale.min));
    else t = (v - scale.min) / (scale.max - scale.min);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return Math.round(255 * t);
  }

  // The 8-bit picture of an image under the scene's exposure and tone map (error maps: their
  // colour map), cached per setting.
  function picture(sc, entry, img) {
    var key = entry.kind === "radiance" ? sc.exposure + "|" + sc.tonemap : "map";
    if (entry._pic && entry._picKey === key) return entry._pic;
    var cv = document.createElement("canvas");
    cv.width = img.w;
    cv.height = img.h;
    var ctx = cv.getContext("2d"), id = ctx.createImageData(img.w, img.h), o = id.data, d = img.data, n = img.w * img.h;
    if (entry.kind === "radiance") {
      var k = Math.pow(2, sc.exposure), filmic = sc.tonemap === "filmic";
      for (var p = 0; p < n; p++) {
        for (var c = 0; c < 3; c++) {
          var v = d[p * img.c + c] * k;
          o[4 * p + c] = srgb(filmic ? aces(Math.max(v, 0)) : v);
        }
        o[4 * p + 3] = 255;
      }
    } else {
      var scale = sc.data.scales[entry.kind], lut = M.colormaps[scale.colormap];
      for (var q = 0; q < n; q++) {
        var rgb = lut[errorIndex(d[q * img.c], scale)];
        o[4 * q] = rgb[0]; o[4 * q + 1] = rgb[1]; o[4 * q + 2] = rgb[2]; o[4 * q + 3] = 255;
      }
    }
    ctx.putImageData(id, 0, 0);
    entry._pic = cv;
    entry._picKey = key;
    return cv;
  }

  function fmt(v) {
    if (v === null || v === undefined || !isFinite(v)) return "n/a";
    var a = Math.abs(v);
    return a !== 0 && (a < 1e-3 || a >= 1e5) ? v.toExponential(3) : Number(v.toPrecision(4)).toString();
  }

  function el(tag, attrs, text) {
    var e = document.createElement(tag);
    for (var k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }

  // ---------------------------------------------------------------------------------------------
  // One scene

  // `frames`: a sequence's scenes in frame order (data is frames[0]), or undefined for a still.
  function Scene(data, host, frames, seqName) {
    var sc = this;
    sc.data = data;
    sc.frames = frames || null;
    sc.frame = 0;
    sc.byId = {};
    data.images.forEach(function (e) { sc.byId[e.id] = e; });
    sc.exposure = 0;
    sc.tonemap = "clamp";
    sc.view = {scale: 0, cx: data.width / 2, cy: data.height / 2};  // CSS px per image px; centre
    sc.split = 0.5;
    sc.showCrops = true;
    sc.showWorse = true;
    sc.sides = {left: data.left, right: data.right, second: firstError(data) || data.right};

    var title = sc.frames ? seqName : data.name;
    sc.title = title;
    var sec = el("section", {"class": "scene", id: "scene-" + title.replace(/[^A-Za-z0-9_-]/g, "_"), tabindex: "0",
                             "data-scene": sc.frames ? data.name : title});
    if (sc.frames) sec.setAttribute("data-sequence", seqName);
    sc.section = sec;
    sc.heading = el("h3");
    sec.appendChild(sc.heading);
    var controls = el("div", {"class": "controls"});
    if (sc.frames) {  // the frame slider: the same two images of another frame
      var frLab = el("label", {"class": "frame-control"}, "frame ");
      var prev = el("button", {type: "button", "class": "frame-prev", title: "previous frame (,)"}, "\u25C0");
      sc.frameInput = el("input", {"class": "frame", type: "range", min: "0", max: String(sc.frames.length - 1), step: "1",
                                   value: "0", "aria-label": "frame of " + seqName});
      var next = el("button", {type: "button", "class": "frame-next", title: "next frame (.)"}, "\u25B6");
      sc.frameOut = el("output", {"class": "frame-number"});
      prev.addEventListener("click", function () { sc.setFrame(sc.frame - 1); });
      next.addEventListener("click", function () { sc.setFrame(sc.frame + 1); });
      sc.frameInput.addEventListener("input", function () { sc.setFrame(Number(sc.frameInput.value)); });
      frLab.appendChild(prev);
      frLab.appendChild(sc.frameInput);
      frLab.appendChild(next);
      frLab.appendChild(sc.frameOut);
      controls.appendChild(frLab);
    }
    sc.select = {};
    [["left", "left"], ["right", "right"], ["second", "second view"]].forEach(function (p) {
      var lab = el("label", {}, p[1] + " ");
      var s = el("select", {"class": "pick-" + p[0], "aria-label": p[1] + " image of " + title});
      sc.select[p[0]] = s;
      fillSelect(sc, p[0]);
      s.addEventListener("change", function () { sc.set(p[0], s.value); });
      lab.appendChild(s);
      controls.appendChild(lab);
    });
    var swap = el("button", {type: "button", "class": "swap", title: "swap left and right (x)"}, "swap");
    swap.addEventListener("click", function () { sc.swap(); });
    controls.appendChild(swap);
    var expLab = el("label", {}, "exposure ");
    sc.expInput = el("input", {"class": "exposure", type: "range", min: "-8", max: "8", step: "0.25", value: "0"});
    sc.expOut = el("output", {}, "0");
    sc.expInput.addEventListener("input", function () { sc.setExposure(Number(sc.expInput.value)); });
    expLab.appendChild(sc.expInput);
    expLab.appendChild(sc.expOut);
    expLab.appendChild(document.createTextNode(" stops"));
    controls.appendChild(expLab);
    var tmLab = el("label", {}, "tone map ");
    sc.tmSelect = el("select", {"class": "tonemap"});
    sc.tmSelect.appendChild(el("option", {value: "clamp"}, "linear, clamped"));
    sc.tmSelect.appendChild(el("option", {value: "filmic"}, "filmic (ACES fit)"));
    sc.tmSelect.addEventListener("change", function () { sc.tonemap = sc.tmSelect.value; sc.draw(); });
    tmLab.appendChild(sc.tmSelect);
    controls.appendChild(tmLab);
    var fit = el("button", {type: "button", "class": "fit", title: "fit the image (r)"}, "fit");
    fit.addEventListener("click", function () { sc.fit(); });
    controls.appendChild(fit);
    var cropLab = el("label", {});
    var cropBox = el("input", {type: "checkbox", checked: ""});
    cropBox.addEventListener("change", function () { sc.showCrops = cropBox.checked; sc.draw(); });
    cropLab.appendChild(cropBox);
    cropLab.appendChild(document.createTextNode(" crops"));
    controls.appendChild(cropLab);
    // The tiles where the method shown is worse than its input (records' worse_tiles): orange
    // above the input's error, red above twice it.
    var worseLab = el("label", {title: "16x16 tiles whose 8-bit error is above the input's (orange) or twice it (red)"});
    var worseBox = el("input", {type: "checkbox", "class": "worse-tiles", checked: ""});
    worseBox.addEventListener("change", function () { sc.showWorse = worseBox.checked; sc.draw(); });
    worseLab.appendChild(worseBox);
    worseLab.appendChild(document.createTextNode(" worse than input"));
    controls.appendChild(worseLab);
    sec.appendChild(controls);
    sec.appendChild(el("p", {"class": "keys"}, "Wheel: zoom; drag: pan; drag the handle: move the split. Keys (pointer over the " +
      "scene): 1-9 right image, shift+1-9 left image, up/down next/previous right image, shift+up/down left, x swap, " +
      "e / shift+e exposure up/down, t tone map, r fit." + (sc.frames ? " Comma / period: previous / next frame." : "")));

    var views = el("div", {"class": "views"});
    sc.views = [makeView(sc, "split", views), makeView(sc, "second", views)];
    sc.setHeading();
    sec.appendChild(views);
    sc.bars = el("div", {"class": "colourbars"});
    sec.appendChild(sc.bars);
    sc.loupe = el("div", {"class": "loupe", hidden: ""});
    sec.appendChild(sc.loupe);
    sc.cropBox = cropTable(sc);
    sec.appendChild(sc.cropBox);
    sec.addEventListener("pointerenter", function () { active = sc; });
    sec.addEventListener("focusin", function () { active = sc; });
    host.appendChild(sec);
    sc.ensure();
  }

  // A selector's options: the scene's (frame's) images, each with its record's number.
  function fillSelect(sc, side) {
    var s = sc.select[side];
    s.textContent = "";
    sc.data.images.forEach(function (e) {
      var m = e.metrics || {}, extra = "";
      if (e.kind === "radiance" && m.mse !== undefined) extra = " (mse " + fmt(m.mse) + ")";
      else if (e.kind !== "radiance" && m[e.kind] !== undefined) extra = " (mean " + fmt(m[e.kind]) + ")";
      s.appendChild(el("option", {value: e.id, "data-method": e.method, "data-kind": e.kind}, e.label + extra));
    });
    s.value = sc.sides[side];
  }

  Scene.prototype.setHeading = function () {
    var d = this.data;
    this.heading.textContent = this.title + (this.frames ? ", frame " + d.frame + " (" + (this.frame + 1) + " of " +
      this.frames.length + ": " + d.name + ")" : "") + " (" + d.width + "x" + d.height + ", " + d.spp + " spp input" +
      (d.seed !== null ? ", seed " + d.seed : "") + ")";
    if (this.frames) {
      this.frameInput.value = String(this.frame);
      this.frameOut.textContent = d.frame + " / " + (this.frames.length - 1);
      this.section.dataset.frame = String(d.frame);
      this.section.dataset.scene = d.name;
    }
  };

  // Frame t of the sequence: each side shows the image of the same method and kind in that frame
  // (the frame's default where it has none); zoom, pan, split, exposure and tone map stay.
  Scene.prototype.setFrame = function (t) {
    if (!this.frames) return;
    t = Math.max(0, Math.min(this.frames.length - 1, t));
    if (t === this.frame) return;
    var sc = this, old = sc.entries(), data = sc.frames[t];
    function same(entry, fallback) {
      for (var i = 0; entry && i < data.images.length; i++)
        if (data.images[i].method === entry.method && data.images[i].kind === entry.kind) return data.images[i].id;
      return fallback;
    }
    sc.sides = {left: same(old.left, data.left), right: same(old.right, data.right),
                second: same(old.second, firstError(data) || data.right)};
    sc.frame = t;
    sc.data = data;
    sc.byId = {};
    data.images.forEach(function (e) { sc.byId[e.id] = e; });
    ["left", "right", "second"].forEach(function (side) { fillSelect(sc, side); });
    var crops = cropTable(sc);
    sc.section.replaceChild(crops, sc.cropBox);
    sc.cropBox = crops;
    sc._barsKey = null;
    sc.setHeading();
    sc.ensure();
    // The next frame's two images, so that stepping on does not wait for them.
    var nd = sc.frames[t + 1];
    if (nd) {
      nd.images.forEach(function (e) {
        [sc.byId[sc.sides.left], sc.byId[sc.sides.right]].forEach(function (x) {
          if (x && e.method === x.method && e.kind === x.kind) DNB.load(e).catch(function () {});
        });
      });
    }
  };

  function firstError(data) {
    for (var i = 0; i < data.images.length; i++) if (data.images[i].kind !== "radiance" && data.images[i].method === idMethod(data, data.left))
      return data.images[i].id;
    return null;
  }
  function idMethod(data, id) {
    for (var i = 0; i < data.images.length; i++) if (data.images[i].id === id) return data.images[i].method;
    return null;
  }

  function makeView(sc, which, parent) {
    var v = {which: which};
    v.box = el("div", {"class": "view view-" + which, "data-view": which});
    v.box.style.aspectRatio = sc.data.width + " / " + sc.data.height;
    v.canvas = el("canvas", {"class": "view-canvas"});
    v.box.appendChild(v.canvas);
    if (which === "split") {
      v.labelL = el("span", {"class": "label label-left"});
      v.labelR = el("span", {"class": "label label-right"});
      v.box.appendChild(v.labelL);
      v.box.appendChild(v.labelR);
    } else {
      v.labelL = el("span", {"class": "label label-left"});
      v.box.appendChild(v.labelL);
    }
    parent.appendChild(v.box);
    var drag = null;
    v.canvas.addEventListener("pointerdown", function (ev) {
      var r = v.canvas.getBoundingClientRect(), x = ev.clientX - r.left;
      var onHandle = which === "split" && Math.abs(x - sc.split * r.width) < 14;
      drag = {handle: onHandle, x: ev.clientX, y: ev.clientY, cx: sc.view.cx, cy: sc.view.cy};
      v.canvas.setPointerCapture(ev.pointerId);
      ev.preventDefault();  // no text selection; but then no focus either, so give it to the scene
      sc.section.focus({preventScroll: true});  // keys reach it even after a selector had focus
    });
    v.canvas.addEventListener("pointermove", function (ev) {
      var r = v.canvas.getBoundingClientRect();
      if (drag && drag.handle) {
        sc.split = Math.min(1, Math.max(0, (ev.clientX - r.left) / r.width));
        sc.draw();
      } else if (drag) {
        sc.view.cx = drag.cx - (ev.clientX - drag.x) / sc.view.scale;
        sc.view.cy = drag.cy - (ev.clientY - drag.y) / sc.view.scale;
        sc.draw();
      }
      var near = which === "split" && Math.abs(ev.clientX - r.left - sc.split * r.width) < 14;
      v.canvas.style.cursor = near || (drag && drag.handle) ? "ew-resize" : drag ? "grabbing" : "crosshair";
      sc.showLoupe(v, ev.clientX - r.left, ev.clientY - r.top);
    });
    v.canvas.addEventListener("pointerup", function () { drag = null; });
    v.canvas.addEventListener("pointerleave", function () { sc.loupe.hidden = true; });
    v.canvas.addEventListener("wheel", function (ev) {
      ev.preventDefault();
      var r = v.canvas.getBoundingClientRect();
      sc.zoomAt(v, ev.clientX - r.left, ev.clientY - r.top, Math.pow(2, -ev.deltaY / 300));
    }, {passive: false});
    if (window.ResizeObserver) new ResizeObserver(function () { sc.draw(); }).observe(v.box);
    return v;
  }

  Scene.prototype.entries = function () {
    return {left: this.byId[this.sides.left], right: this.byId[this.sides.right], second: this.byId[this.sides.second]};
  };

  // Loads what the views show, then draws.
  Scene.prototype.ensure = function () {
    var sc = this, e = sc.entries();
    Promise.all([DNB.load(e.left), DNB.load(e.right), DNB.load(e.second)]).then(function () { sc.draw(); },
                                                                                 function () {});
  };

  Scene.prototype.set = function (side, id) {
    if (!this.byId[id]) return;
    this.sides[side] = id;
    this.select[side].value = id;
    this.ensure();
  };
  Scene.prototype.swap = function () {
    var l = this.sides.left;
    this.set("left", this.sides.right);
    this.set("right", l);
  };
  Scene.prototype.step = function (side, d) {
    var ids = this.data.images.map(function (e) { return e.id; });
    var i = ids.indexOf(this.sides[side]);
    this.set(side, ids[(i + d + ids.length) % ids.length]);
  };
  Scene.prototype.setExposure = function (v) {
    this.exposure = Math.max(-8, Math.min(8, v));
    this.expInput.value = String(this.exposure);
    this.expOut.textContent = String(this.exposure);
    this.draw();
  };
  Scene.prototype.fit = function () {
    this.view.scale = 0;
    this.view.cx = this.data.width / 2;
    this.view.cy = this.data.height / 2;
    this.draw();
  };
  Scene.prototype.zoomTo = function (c) {
    var w = this.views[0].canvas.clientWidth || 1;
    this.view.scale = Math.min(w / c.w, (w * this.data.height / this.data.width) / c.h) * 0.9;
    this.view.cx = c.x + c.w / 2;
    this.view.cy = c.y + c.h / 2;
    this.draw();
  };
  Scene.prototype.zoomAt = function (v, x, y, f) {
    var s = this.view.scale, w = v.canvas.clientWidth, h = v.canvas.clientHeight;
    var ix = this.view.cx + (x - w / 2) / s, iy = this.view.cy + (y - h / 2) / s;  // image point under the pointer
    var ns = Math.max(0.05, Math.min(64, s * f));
    this.view.scale = ns;
    this.view.cx = ix - (x - w / 2) / ns;
    this.view.cy = iy - (y - h / 2) / ns;
    this.draw();
  };

  Scene.prototype.draw = function () {
    var sc = this, e = sc.entries();
    sc.views.forEach(function (v) { drawView(sc, v, e); });
    sc.drawBars(e);
  };

  function drawView(sc, v, e) {
    var w = v.box.clientWidth, h = v.box.clientHeight, dpr = window.devicePixelRatio || 1;
    if (!w || !h) return;
    if (v.canvas.width !== Math.round(w * dpr) || v.canvas.height !== Math.round(h * dpr)) {
      v.canvas.width = Math.round(w * dpr);
      v.canvas.height = Math.round(h * dpr);
    }
    if (!sc.view.scale) sc.view.scale = Math.min(w / sc.data.width, h / sc.data.height);
    var s = sc.view.scale, ctx = v.canvas.getContext("2d");
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#444";
    ctx.fillRect(0, 0, v.canvas.width, v.canvas.height);
    ctx.imageSmoothingEnabled = false;
    var tx = w / 2 - sc.view.cx * s, ty = h / 2 - sc.view.cy * s;
    function paint(entry, x0, x1) {
      var img = entry && DNB_loaded(entry);
      if (!img) return;
      ctx.save();
      ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
      ctx.beginPath();
      ctx.rect(x0, 0, x1 - x0, h);
      ctx.clip();
      ctx.setTransform(dpr * s, 0, 0, dpr * s, dpr * tx, dpr * ty);
      ctx.drawImage(picture(sc, entry, img), 0, 0);
      if (sc.showWorse && entry.worse_tiles) {
        ctx.lineWidth = 1.5 / s;
        entry.worse_tiles.forEach(function (t) {
          ctx.strokeStyle = t[4] > 2 ? "#ff1744" : "#ff9100";
          ctx.strokeRect(t[0] + 0.5 / s, t[1] + 0.5 / s, t[2] - 1 / s, t[3] - 1 / s);
        });
      }
      ctx.restore();
    }
    if (v.which === "split") {
      var xs = sc.split * w;
      paint(e.left, 0, xs);
      paint(e.right, xs, w);
      v.labelL.textContent = "\u25C0 " + e.left.label;
      v.labelR.textContent = e.right.label + " \u25B6";
    } else {
      paint(e.second, 0, w);
      v.labelL.textContent = e.second.label;
    }
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    if (sc.showCrops) sc.data.crops.forEach(function (c, i) {
      ctx.strokeStyle = "#00e5ff";
      ctx.lineWidth = 1.5;
      ctx.strokeRect(tx + c.x * s, ty + c.y * s, c.w * s, c.h * s);
      ctx.fillStyle = "#00e5ff";
      ctx.font = "bold 13px system-ui, sans-serif";
      ctx.fillText(String(i + 1), tx + c.x * s + 3, ty + c.y * s + 14);
    });
    if (v.which === "split") {  // the handle: a line with a round grip and arrows
      var hx = sc.split * w;
      ctx.fillStyle = "rgba(0,0,0,0.6)";
      ctx.fillRect(hx - 2, 0, 4, h);
      ctx.fillStyle = "#fff";
      ctx.fillRect(hx - 1, 0, 2, h);
      ctx.beginPath();
      ctx.arc(hx, h / 2, 13, 0, 2 * Math.PI);
      ctx.fillStyle = "#fff";
      ctx.fill();
      ctx.strokeStyle = "#222";
      ctx.lineWidth = 1.5;
      ctx.stroke();
      ctx.fillStyle = "#222";
      ctx.beginPath();
      ctx.moveTo(hx - 3, h / 2 - 6); ctx.lineTo(hx - 9, h / 2); ctx.lineTo(hx - 3, h / 2 + 6);
      ctx.moveTo(hx + 3, h / 2 - 6); ctx.lineTo(hx + 9, h / 2); ctx.lineTo(hx + 3, h / 2 + 6);
      ctx.fill();
    }
    v.canvas.dataset.scale = String(s);
    v.canvas.dataset.cx = String(sc.view.cx);
    v.canvas.dataset.cy = String(sc.view.cy);
  }

  function DNB_loaded(entry) { return entry._img || null; }

  // Colour bars of the error maps on show, each with its scale.
  Scene.prototype.drawBars = function (e) {
    var kinds = [];
    [e.left, e.right, e.second].forEach(function (x) { if (x && x.kind !== "radiance" && kinds.indexOf(x.kind) < 0) kinds.push(x.kind); });
    var key = kinds.join(",");
    if (this._barsKey === key) return;
    this._barsKey = key;
    this.bars.textContent = "";
    var sc = this;
    kinds.forEach(function (k) {
      var scale = sc.data.scales[k], lut = M.colormaps[scale.colormap];
      var fig = el("figure", {"class": "colourbar", "data-kind": k});
      var cv = el("canvas", {width: "256", height: "14"});
      var ctx = cv.getContext("2d");
      for (var i = 0; i < 256; i++) {
        ctx.fillStyle = "rgb(" + lut[i].join(",") + ")";
        ctx.fillRect(i, 0, 1, 14);
      }
      fig.appendChild(cv);
      var ticks = el("div", {"class": "ticks"});
      var vals = [];
      if (scale.log) for (var d = Math.log10(scale.min); d <= Math.log10(scale.max) + 1e-9; d++) vals.push(Math.pow(10, d));
      else for (var t = 0; t <= 4; t++) vals.push(scale.min + (scale.max - scale.min) * t / 4);
      vals.forEach(function (v) {
        var pos = errorIndex(v, scale) / 255;
        var s = el("span", {}, scale.log ? "1e" + Math.round(Math.log10(v)) : fmt(v));
        s.style.left = (100 * pos) + "%";
        ticks.appendChild(s);
      });
      fig.appendChild(ticks);
      var names = {flip: "FLIP error", hdrflip: "HDR-FLIP error", relmse: "relMSE, per pixel"};
      fig.appendChild(el("figcaption", {}, names[k] + " (" + scale.colormap + ", " + (scale.log ? "log scale" : "linear") +
                                             ", " + fmt(scale.min) + " to " + fmt(scale.max) + ")"));
      sc.bars.appendChild(fig);
    });
  };

  Scene.prototype.showLoupe = function (v, x, y) {
    var sc = this, s = sc.view.scale, w = v.canvas.clientWidth, h = v.canvas.clientHeight;
    var ix = Math.floor(sc.view.cx + (x - w / 2) / s), iy = Math.floor(sc.view.cy + (y - h / 2) / s);
    if (ix < 0 || iy < 0 || ix >= sc.data.width || iy >= sc.data.height) { sc.loupe.hidden = true; return; }
    var e = sc.entries(), sides = v.which === "split" ? [e.left, e.right] : [e.second, e.right];
    sc.loupe.textContent = "";
    sc.loupe.appendChild(el("div", {"class": "loupe-pos"}, "pixel (" + ix + ", " + iy + ")"));
    var R = 5, Z = 8;  // an 11x11 neighbourhood, 8 px per pixel
    sides.forEach(function (entry) {
      var img = DNB_loaded(entry);
      if (!img) return;
      var box = el("div", {"class": "loupe-side"});
      var cv = el("canvas", {width: String((2 * R + 1) * Z), height: String((2 * R + 1) * Z)});
      var ctx = cv.getContext("2d");
      ctx.imageSmoothingEnabled = false;
      ctx.fillStyle = "#444";
      ctx.fillRect(0, 0, cv.width, cv.height);
      ctx.drawImage(picture(sc, entry, img), ix - R, iy - R, 2 * R + 1, 2 * R + 1, 0, 0, cv.width, cv.height);
      ctx.strokeStyle = "#00e5ff";
      ctx.strokeRect(R * Z + 0.5, R * Z + 0.5, Z - 1, Z - 1);
      box.appendChild(cv);
      var p = (iy * img.w + ix) * img.c, vals = [];
      for (var c = 0; c < img.c; c++) vals.push(fmt(img.data[p + c]));
      box.appendChild(el("div", {"class": "loupe-label"}, entry.label));
      box.appendChild(el("div", {"class": "loupe-value"}, (img.c === 3 ? "RGB " : "") + vals.join(", ")));
      sc.loupe.appendChild(box);
    });
    sc.loupe.hidden = false;
  };

  // Each crop: where it is, why, and each method's mean error maps there (best marked).
  function cropTable(sc) {
    var wrap = el("div", {"class": "crops"});
    sc.data.crops.forEach(function (c, i) {
      var kinds = [];
      Object.keys(c.metrics).forEach(function (m) { Object.keys(c.metrics[m]).forEach(function (k) { if (kinds.indexOf(k) < 0) kinds.push(k); }); });
      var box = el("div", {"class": "crop table-scroll"});
      var head = el("p", {}, "Crop " + (i + 1) + ": x " + c.x + ", y " + c.y + ", " + c.w + "x" + c.h + " (" + c.why + " of " + c.of + ") ");
      var b = el("button", {type: "button", "class": "zoom-crop"}, "zoom to crop " + (i + 1));
      b.addEventListener("click", function () { sc.zoomTo(c); });
      head.appendChild(b);
      box.appendChild(head);
      var t = el("table", {"class": "crop-metrics"});
      var tr = el("tr");
      tr.appendChild(el("th", {}, "method"));
      var names = {flip: "mean FLIP", hdrflip: "mean HDR-FLIP", relmse: "mean relMSE"};
      kinds.forEach(function (k) { tr.appendChild(el("th", {}, names[k] || k)); });
      var thead = el("thead");
      thead.appendChild(tr);
      t.appendChild(thead);
      var tb = el("tbody"), best = {};
      kinds.forEach(function (k) {
        Object.keys(c.metrics).forEach(function (m) {
          if (m === "input") return;
          var v = c.metrics[m][k];
          if (v !== undefined && (best[k] === undefined || v < best[k])) best[k] = v;
        });
      });
      Object.keys(c.metrics).forEach(function (m) {
        var row = el("tr");
        var name = el("td", {});
        var chip = el("span", {"class": "chip"});
        chip.style.background = M.styles[m] || "#888";
        name.appendChild(chip);
        name.appendChild(document.createTextNode(m));
        row.appendChild(name);
        kinds.forEach(function (k) {
          var v = c.metrics[m][k];
          var td = el("td", {}, fmt(v));
          if (m !== "input" && v !== undefined && v === best[k]) { td.className = "best"; td.title = "lowest of the methods"; }
          row.appendChild(td);
        });
        tb.appendChild(row);
      });
      t.appendChild(tb);
      box.appendChild(t);
      wrap.appendChild(box);
    });
    return wrap;
  }

  // Keep the decoded data on the entry once loaded.
  var load = DNB.load;
  DNB.load = function (entry) {
    return load(entry).then(function (img) { entry._img = img; return img; });
  };

  // ---------------------------------------------------------------------------------------------
  // The keyboard, as in tev (up/down through the images) and JERI (number keys)

  document.addEventListener("keydown", function (ev) {
    if (!active || ev.ctrlKey || ev.metaKey || ev.altKey) return;
    var t = ev.target && ev.target.tagName;
    if (t === "SELECT" || t === "INPUT" && ev.target.type !== "checkbox" && ev.target.type !== "range") return;
    var sc = active, side = ev.shiftKey ? "left" : "right";
    var m = /^Digit([1-9])$/.exec(ev.code);
    if (m) {
      var entry = sc.data.images[Number(m[1]) - 1];
      if (entry) sc.set(side, entry.id);
    } else if (ev.key === "ArrowDown") sc.step(side, 1);
    else if (ev.key === "ArrowUp") sc.step(side, -1);
    else if (ev.key === "x") sc.swap();
    else if (ev.key === "e") sc.setExposure(sc.exposure + 0.5);
    else if (ev.key === "E") sc.setExposure(sc.exposure - 0.5);
    else if (ev.key === "t") { sc.tonemap = sc.tonemap === "clamp" ? "filmic" : "clamp"; sc.tmSelect.value = sc.tonemap; sc.draw(); }
    else if (ev.key === "r") sc.fit();
    else if (ev.key === "," && sc.frames) sc.setFrame(sc.frame - 1);
    else if (ev.key === "." && sc.frames) sc.setFrame(sc.frame + 1);
    else return;
    ev.preventDefault();
  });

  var host = document.getElementById("scenes");
  var nav = document.getElementById("scene-index");
  // A sequence's frames are one viewer (manifest.sequences: each with its scenes in frame order).
  var frameOf = {};  // scene position in M.scenes -> its sequence, for the sequence's first frame only
  var inSequence = {};
  (M.sequences || []).forEach(function (q) {
    if (!q.scenes.length) return;
    frameOf[q.scenes[0]] = q;
    q.scenes.forEach(function (i) { inSequence[i] = true; });
  });
  M.scenes.forEach(function (d, i) {
    if (inSequence[i] && !frameOf[i]) return;
    var q = frameOf[i];
    var sc = q ? new Scene(d, host, q.scenes.map(function (k) { return M.scenes[k]; }), q.name) : new Scene(d, host);
    scenes.push(sc);
    if (nav) {
      var li = el("li");
      li.appendChild(el("a", {href: "#" + sc.section.id}, q ? q.name + " (" + q.scenes.length + " frames)" : d.name));
      nav.appendChild(li);
    }
  });
  if (scenes.length) active = scenes[0];
  // The sections did not exist when the browser looked for the address's #scene-... anchor.
  if (location.hash && location.hash.indexOf("#scene-") === 0) {
    var target = document.getElementById(decodeURIComponent(location.hash.slice(1)));
    if (target) target.scrollIntoView();
  }
  window.dnbViewer = {scenes: scenes};  // for the page test (tests/apps/report_page_test.cpp)
})();
