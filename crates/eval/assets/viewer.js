// cvtrace comparison viewer: builds every scene from window.CVTRACE_DATA (data.js).
// Works from file:// with no server: no fetch, no modules, no external resources.
"use strict";
(function () {
  const D = window.CVTRACE_DATA;
  const main = document.getElementById("scenes");
  const body = document.body;
  const SVG_NS = "http://www.w3.org/2000/svg";

  if (!D || !D.results) {
    main.appendChild(el("p", { class: "warning", text: "data.js is missing or did not load: regenerate the report with `cvtrace report`." }));
    body.dataset.loaded = "0/0";
    body.dataset.ready = "1";
    return;
  }

  // ---- formatting: the same rule as cvtrace_eval::table::fmt_num -------------------------
  function fmt(x) {
    if (x === null || x === undefined || !isFinite(x)) return "–";
    if (x === 0) return "0";
    const a = Math.abs(x);
    if (a >= 1e-3 && a < 1e5) return x.toFixed(Math.max(0, 3 - Math.floor(Math.log10(a))));
    return x.toExponential(3).replace("e+", "e");
  }
  function fmtSec(s) {
    if (s === null || s === undefined || !isFinite(s)) return "–";
    return s < 10 ? s.toFixed(3) : s.toFixed(1);
  }

  function el(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined) continue;
      if (k === "text") e.textContent = v;
      else if (k === "class") e.className = v;
      else if (k === "style") e.style.cssText = v;
      else if (k.startsWith("data-")) e.setAttribute(k, v);
      else e[k] = v;
    }
    for (const c of children) if (c !== null && c !== undefined) e.appendChild(typeof c === "string" ? document.createTextNode(c) : c);
    return e;
  }

  // Short labels travel with the results (each method's `short`); the key stands in where absent.
  const SHORT = {};
  for (const scene of D.results.scenes) for (const m of scene.methods) if (m.short && !(m.name in SHORT)) SHORT[m.name] = m.short;
  const short = (k) => SHORT[k] || k;

  // ---- synchronised zoom and pan ----------------------------------------------------------
  // One state per scene: zoom z (1 = fit) and the view centre (cx, cy) in image-normalised
  // coordinates, so boxes of any size show the same crop.
  function makeState(scene, view) {
    return { scene, view, z: 1, cx: 0.5, cy: 0.5, ev: 0, viewports: new Set(), listeners: [] };
  }
  function zMax(st) {
    return Math.max(4, Math.max(st.scene.width, st.scene.height) / 4);
  }
  function fitSize(vp, st) {
    const W = vp.clientWidth, H = vp.clientHeight;
    const s = Math.min(W / st.scene.width, H / st.scene.height);
    return [st.scene.width * s, st.scene.height * s, W, H];
  }
  function clampState(st) {
    st.z = Math.min(Math.max(st.z, 1), zMax(st));
    const half = 0.5 / st.z;
    st.cx = Math.min(Math.max(st.cx, half), 1 - half);
    st.cy = Math.min(Math.max(st.cy, half), 1 - half);
  }
  function layout(vp, st) {
    const img = vp.querySelector("img");
    if (!img) return;
    const [fw, fh, W, H] = fitSize(vp, st);
    if (!W) return;
    const w = fw * st.z, h = fh * st.z;
    img.style.width = w + "px";
    img.style.height = h + "px";
    img.style.transform = "translate(" + (W / 2 - st.cx * w) + "px," + (H / 2 - st.cy * h) + "px)";
    vp.style.filter = vp.classList.contains("photo") && st.ev !== 0 ? "url(#" + st.view.slug + "-exposure)" : "";
  }
  function apply(st) {
    clampState(st);
    for (const vp of st.viewports) layout(vp, st);
    for (const f of st.listeners) f();
  }
  // Image coordinates (0..1) under a client point of viewport vp.
  function imagePoint(vp, st, clientX, clientY) {
    const r = vp.getBoundingClientRect();
    const [fw, fh, W, H] = fitSize(vp, st);
    const w = fw * st.z, h = fh * st.z;
    return [(clientX - r.left - (W / 2 - st.cx * w)) / w, (clientY - r.top - (H / 2 - st.cy * h)) / h, clientX - r.left, clientY - r.top, w, h, W, H];
  }
  function attachInteraction(vp, st, onPixel) {
    st.viewports.add(vp);
    vp.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      const [u, v, px, py, , , W, H] = imagePoint(vp, st, ev.clientX, ev.clientY);
      const factor = Math.pow(1.25, -Math.sign(ev.deltaY) * Math.min(3, Math.max(1, Math.abs(ev.deltaY) / 100)));
      st.z = Math.min(Math.max(st.z * factor, 1), zMax(st));
      const [fw, fh] = fitSize(vp, st);
      // Keep the image point under the cursor fixed.
      st.cx = u - (px - W / 2) / (fw * st.z);
      st.cy = v - (py - H / 2) / (fh * st.z);
      apply(st);
      saveHash(st);
    }, { passive: false });
    let drag = null;
    const report = (ev) => {
      const [u, v] = imagePoint(vp, st, ev.clientX, ev.clientY);
      if (onPixel && u >= 0 && u < 1 && v >= 0 && v < 1) onPixel(Math.floor(u * st.scene.width), Math.floor(v * st.scene.height), vp.dataset.method);
    };
    vp.addEventListener("pointerdown", (ev) => {
      report(ev);
      drag = { x: ev.clientX, y: ev.clientY, moved: false };
      vp.setPointerCapture(ev.pointerId);
      vp.classList.add("dragging");
    });
    vp.addEventListener("pointermove", (ev) => {
      if (drag) {
        const [fw, fh] = fitSize(vp, st);
        const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
        if (Math.abs(dx) + Math.abs(dy) > 2) drag.moved = true;
        st.cx -= dx / (fw * st.z);
        st.cy -= dy / (fh * st.z);
        drag.x = ev.clientX;
        drag.y = ev.clientY;
        apply(st);
      }
      report(ev);
    });
    const end = (ev) => {
      if (!drag) return;
      vp.classList.remove("dragging");
      const click = !drag.moved;
      drag = null;
      saveHash(st);
      if (click && vp.dataset.flipIndex !== undefined && ev.type === "pointerup") openFlip(st, Number(vp.dataset.flipIndex));
    };
    vp.addEventListener("pointerup", end);
    vp.addEventListener("pointercancel", end);
  }

  // View state in the URL hash (#z=4&cx=0.31&cy=0.62&ev=1) so a crop can be shared.
  function readHash() {
    const p = new URLSearchParams(location.hash.replace(/^#/, ""));
    const num = (k) => (p.has(k) && isFinite(Number(p.get(k))) ? Number(p.get(k)) : null);
    return { z: num("z"), cx: num("cx"), cy: num("cy"), ev: num("ev"), flip: num("flip"), scene: p.get("scene") };
  }
  let hashTimer = null;
  function saveHash(st) {
    clearTimeout(hashTimer);
    hashTimer = setTimeout(() => {
      const p = new URLSearchParams({ scene: st.view.slug, z: st.z.toFixed(3), cx: st.cx.toFixed(4), cy: st.cy.toFixed(4), ev: String(st.ev) });
      try { history.replaceState(null, "", "#" + p.toString()); } catch (e) { /* some file:// setups forbid it */ }
    }, 250);
  }

  // ---- exposure: a linear-light gain, exact for unclipped preview values --------------------
  function exposureFilter(slug) {
    const svg = document.createElementNS(SVG_NS, "svg");
    svg.setAttribute("width", "0");
    svg.setAttribute("height", "0");
    svg.setAttribute("aria-hidden", "true");
    svg.style.position = "absolute";
    const filter = document.createElementNS(SVG_NS, "filter");
    filter.setAttribute("id", slug + "-exposure");
    filter.setAttribute("color-interpolation-filters", "linearRGB");
    const transfer = document.createElementNS(SVG_NS, "feComponentTransfer");
    const funcs = ["feFuncR", "feFuncG", "feFuncB"].map((n) => {
      const f = document.createElementNS(SVG_NS, n);
      f.setAttribute("type", "linear");
      f.setAttribute("slope", "1");
      transfer.appendChild(f);
      return f;
    });
    filter.appendChild(transfer);
    svg.appendChild(filter);
    document.body.appendChild(svg);
    return (ev) => funcs.forEach((f) => f.setAttribute("slope", String(Math.pow(2, ev))));
  }

  // ---- linear values for the pixel readout ---------------------------------------------------
  // images/<scene>/pixels.js (little-endian f32 in base64) is a plain script, since a page from
  // file:// may not fetch; it is loaded when a pixel is first pointed at, not with the page.
  const pixelCache = {};
  function b64View(text) {
    const bin = atob(text);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new DataView(bytes.buffer);
  }
  function decodePixels(d) {
    const one = (e) => (e ? { rgb: b64View(e.rgb), relmse: e.relmse ? b64View(e.relmse) : null, flip: e.flip ? b64View(e.flip) : null } : null);
    const methods = {};
    for (const [k, e] of Object.entries(d.methods || {})) methods[k] = one(e);
    return { width: d.width, height: d.height, reference: one(d.reference), methods };
  }
  // The decoded values of a scene, or null while they load (then `onLoad` runs once they have).
  function pixelData(view, onLoad) {
    const c = pixelCache[view.slug];
    if (c && c.data) return c.data;
    const raw = window.CVTRACE_PIXELS && window.CVTRACE_PIXELS[view.slug];
    if (raw) {
      pixelCache[view.slug] = { data: decodePixels(raw) };
      return pixelCache[view.slug].data;
    }
    if (!c) {
      pixelCache[view.slug] = { loading: true };
      const script = el("script", { src: view.pixels });
      script.addEventListener("load", onLoad);
      script.addEventListener("error", () => { pixelCache[view.slug] = { failed: true }; onLoad(); });
      document.head.appendChild(script);
    }
    return null;
  }
  // Linear RGB, relMSE and FLIP of one image at pixel i (null where the image has no values).
  function pixelValues(e, i) {
    if (!e) return null;
    const g = (c) => e.rgb.getFloat32((3 * i + c) * 4, true);
    return { rgb: [g(0), g(1), g(2)], relmse: e.relmse ? e.relmse.getFloat32(4 * i, true) : null, flip: e.flip ? e.flip.getFloat32(4 * i, true) : null };
  }

  // ---- one scene -------------------------------------------------------------------------------
  const states = [];
  const hash = readHash();

  function box(st, entry, index, onPixel) {
    const vp = el("div", { class: "viewport" + (entry.photo ? " photo" : ""), style: "aspect-ratio:" + st.scene.width + " / " + st.scene.height });
    vp.dataset.flipIndex = String(index);
    vp.dataset.method = entry.key;
    vp.dataset.kind = entry.kind;
    vp.title = "click: flip view · wheel: zoom · drag: pan";
    vp.appendChild(el("img", { src: entry.src, alt: entry.label, draggable: false, "data-method": entry.key }));
    attachInteraction(vp, st, onPixel);
    const caption = el("figcaption", {},
      el("span", { class: "name", title: entry.label }, el("span", { class: "swatch", style: "background:" + entry.color }), entry.label),
      el("span", { class: "num", text: entry.caption || "\u00a0" }));
    return el("figure", { class: "box", "data-method": entry.key }, vp, caption);
  }

  function buildScene(scene, view) {
    const st = makeState(scene, view);
    states.push(st);
    const setExposure = exposureFilter(view.slug);
    const section = el("section", { class: "scene", id: view.slug });
    const n = scene.spp_per_stream;
    const ref = scene.reference;
    const meta = el("div", { class: "meta" });
    meta.append(el("b", { text: scene.width + "×" + scene.height }), " · ");
    if (n > 0) meta.append("PT and CRN streams at ", el("b", { text: n + " spp" }), " each (", el("b", { text: 2 * n + " spp" }), " total) · ");
    meta.append(
      el("b", { text: scene.seeds + (scene.seeds === 1 ? " seed" : " seeds") }), " · reference ",
      el("b", { text: ref.path }), ref.spp ? " (" + ref.spp + " spp)" : "",
      ref.noise ? " · reference noise relMSE " : "", ref.noise ? el("b", { text: fmt(ref.noise.relmse), "data-key": view.slug + "/reference/noise" }) : "");
    section.append(el("h2", { text: scene.name }), meta);
    for (const w of scene.warnings || []) section.appendChild(el("div", { class: "warning", text: "⚠ " + w }));

    // Toolbar: exposure, zoom, pixel readout.
    const evValue = el("span", { class: "value" });
    const zoomValue = el("span", { class: "value" });
    const readout = el("span", { class: "readout", text: "pixel –" });
    const slider = el("input", { type: "range", min: "-6", max: "6", step: "0.25", value: "0" });
    slider.addEventListener("input", () => { st.ev = Number(slider.value); setExposure(st.ev); apply(st); saveHash(st); });
    const fitBtn = el("button", { text: "Fit", type: "button" });
    fitBtn.addEventListener("click", () => { st.z = 1; st.cx = 0.5; st.cy = 0.5; apply(st); saveHash(st); });
    const oneBtn = el("button", { text: "1:1", type: "button" });
    oneBtn.addEventListener("click", () => {
      const vp = section.querySelector(".grid .viewport");
      if (vp) { st.z = (scene.width / (vp.clientWidth * (window.devicePixelRatio || 1))); apply(st); saveHash(st); }
    });
    const evReset = el("button", { text: "0 EV", type: "button" });
    evReset.addEventListener("click", () => { slider.value = "0"; slider.dispatchEvent(new Event("input")); });
    st.listeners.push(() => {
      evValue.textContent = (st.ev > 0 ? "+" : "") + st.ev.toFixed(2) + " EV";
      zoomValue.textContent = st.z.toFixed(st.z < 10 ? 2 : 1) + "×";
      slider.value = String(st.ev);
    });
    section.appendChild(el("div", { class: "toolbar" },
      el("label", {}, "Exposure", slider, evValue), evReset,
      el("label", {}, "Zoom", zoomValue), fitBtn, oneBtn, readout,
      el("span", { class: "hint", text: "hover or tap: pixel values · wheel: zoom · drag: pan · click: flip view (1–9, ←/→)" })));
    // The readout table: one row per image, filled for the pixel under the cursor.
    const readoutRows = {};
    const readoutTable = el("table", { class: "results readout-table" });
    readoutTable.appendChild(el("thead", {}, el("tr", {}, ...["Pixel", "R", "G", "B", "relMSE", "FLIP"].map((h) => el("th", { text: h })))));
    const readoutBody = el("tbody");
    readoutTable.appendChild(readoutBody);
    const onPixel = (x, y, key) => {
      st.pixel = [x, y];
      readout.textContent = "pixel (" + x + ", " + y + ")";
      section.dataset.pixel = x + "," + y;
      for (const [k, row] of Object.entries(readoutRows)) row.tr.classList.toggle("hover", k === key);
      if (!readoutBlock.classList.contains("active")) {
        document.querySelectorAll(".readout-block.active").forEach((b) => b.classList.remove("active"));
        readoutBlock.classList.add("active");
      }
      if (!view.pixels) return;
      const data = pixelData(view, () => st.pixel && onPixel(st.pixel[0], st.pixel[1], key));
      if (!data) {
        readoutNote.textContent = pixelCache[view.slug] && pixelCache[view.slug].failed ? view.pixels + " did not load" : "loading the linear values…";
        return;
      }
      readoutNote.textContent = "linear values of pixel (" + x + ", " + y + "); relMSE and FLIP are the per-pixel means over seeds the maps show";
      const i = y * scene.width + x;
      for (const [k, row] of Object.entries(readoutRows)) {
        const v = pixelValues(k === "reference" ? data.reference : data.methods[k], i);
        const cells = v ? v.rgb.concat([v.relmse, v.flip]) : [null, null, null, null, null];
        row.cells.forEach((td, c) => {
          const x = cells[c];
          td.textContent = x === null || x === undefined ? "–" : fmt(x);
          if (x === null || x === undefined) td.removeAttribute("data-value"); else td.setAttribute("data-value", String(x));
        });
      }
      st.flipReadout && st.flipReadout(x, y);
    };
    st.onPixel = onPixel;
    st.pixelAt = (x, y, key) => {
      const data = view.pixels ? pixelData(view, () => {}) : null;
      return data ? pixelValues(key === "reference" ? data.reference : data.methods[key], y * scene.width + x) : null;
    };
    const readoutNote = el("p", { class: "note", text: view.pixels ? "Point at a pixel of any image for its linear values." : "These results carry no linear values (a study by an older cvtrace): only the pixel position is shown." });

    // Image boxes: every method with a preview, then the reference.
    const methods = orderedMethods(scene);
    const main = methods.filter((m) => !m.ablation);
    const ablations = methods.filter((m) => m.ablation);
    const colors = view.colors || {};
    const flipText = (m) => (m.flip_mean !== null && m.flip_mean !== undefined ? " · FLIP " + fmt(m.flip_mean) : "");
    const photoEntry = (m) => ({ key: m.name, label: m.label, src: m.image, photo: true, kind: "image", color: colors[m.name] || "#888", caption: "relMSE " + fmt(m.relmse_mean) + flipText(m) + (m.spp_total ? " · " + m.spp_total + " spp" : "") });
    const photos = main.filter((m) => m.image).map(photoEntry);
    if (ref.image) photos.push({ key: "reference", label: "Reference", src: ref.image, photo: true, kind: "image", color: "#ffffff", caption: ref.spp ? ref.spp + " spp" : "" });
    const maps = main.filter((m) => m.error_map).map((m) => ({ key: m.name, label: m.label, src: m.error_map, photo: false, kind: "relmse", color: colors[m.name] || "#888", caption: "relMSE " + fmt(m.relmse_mean) }));
    const flips = main.filter((m) => m.flip_map).map((m) => ({ key: m.name, label: m.label, src: m.flip_map, photo: false, kind: "flip", color: colors[m.name] || "#888", caption: "FLIP " + fmt(m.flip_mean) }));
    const diffs = main.filter((m) => m.difference_map).map((m) => ({ key: m.name, label: m.label, src: m.difference_map, photo: false, kind: "diff", color: colors[m.name] || "#888", caption: "difference to the reference" }));
    const ablationPhotos = ablations.filter((m) => m.image).map(photoEntry);
    st.entries = photos.concat(maps, flips, diffs, ablationPhotos);

    // Readout rows: the images in the order of the boxes.
    for (const e of photos.concat(ablationPhotos)) {
      const cells = ["R", "G", "B", "relmse", "flip"].map((c) => el("td", { text: "–", "data-key": view.slug + "/pixel/" + e.key + "/" + c }));
      const tr = el("tr", { "data-method": e.key }, el("td", {}, el("span", { class: "swatch", style: "background:" + e.color + ";margin-right:7px" }), e.label), ...cells);
      readoutRows[e.key] = { tr, cells };
      readoutBody.appendChild(tr);
    }
    // A panel in the corner of the window, so it stays in view beside whichever image is pointed
    // at; shown for the scene last pointed at, until closed.
    const closeBtn = el("button", { type: "button", text: "×", title: "close (pointing at a pixel opens it again)" });
    const readoutBlock = el("div", { class: "readout-block" }, el("div", { class: "readout-head" }, el("b", { text: scene.name + " · pixel readout" }), closeBtn), readoutNote, readoutTable);
    closeBtn.addEventListener("click", () => readoutBlock.classList.remove("active"));

    let index = 0;
    if (photos.length) section.appendChild(readoutBlock);
    if (photos.length) {
      section.appendChild(el("h3", { text: "Images" }));
      const grid = el("div", { class: "grid images" });
      for (const e of photos) grid.appendChild(box(st, e, index++, onPixel));
      section.appendChild(grid);
    }
    if (maps.length) {
      section.appendChild(el("h3", { text: "relMSE per pixel" }));
      const grid = el("div", { class: "grid maps" });
      for (const e of maps) grid.appendChild(box(st, e, index++, onPixel));
      // The legend takes the reference's place, so each map sits under its image.
      const scale = scene.error_map_scale;
      if (scale && D.colorbar) {
        grid.appendChild(el("div", { class: "legend" },
          el("div", { class: "legend-title", text: "per-pixel relMSE (log scale, shared by all methods)" }),
          el("img", { src: D.colorbar, alt: "colour scale" }),
          el("div", { class: "legend-ticks" },
            el("span", { text: fmt(Math.pow(10, scale.log10_min)), "data-key": view.slug + "/error_map/min" }),
            el("span", { text: fmt(Math.pow(10, 0.5 * (scale.log10_min + scale.log10_max))) }),
            el("span", { text: fmt(Math.pow(10, scale.log10_max)), "data-key": view.slug + "/error_map/max" })),
          el("div", { class: "legend-note", text: "dark = low error · colour map " + scale.colormap })));
      }
      section.appendChild(grid);
    }
    if (flips.length) {
      section.appendChild(el("h3", { text: "HDR-FLIP per pixel" }));
      const grid = el("div", { class: "grid flips" });
      for (const e of flips) grid.appendChild(box(st, e, index++, onPixel));
      // FLIP's own scale, 0 to 1, the same for every scene and every study.
      const f = scene.flip;
      if (D.flip_colorbar) {
        grid.appendChild(el("div", { class: "legend" },
          el("div", { class: "legend-title", text: "HDR-FLIP error per pixel, mean over " + scene.seeds + (scene.seeds === 1 ? " seed" : " seeds") + " (linear, 0 to 1, as NVIDIA's tool shows it)" }),
          el("img", { src: D.flip_colorbar, alt: "magma colour scale" }),
          el("div", { class: "legend-ticks" }, el("span", { text: "0" }), el("span", { text: "0.5" }), el("span", { text: "1" })),
          el("div", { class: "legend-note", "data-key": view.slug + "/flip/settings", text: "dark = no visible difference · colour map " + (f ? f.colormap : "magma") +
            (f ? " · " + fmt(f.ppd) + " pixels per degree, " + f.num_exposures + " exposures from " + fmt(f.start_exposure) + " to " + fmt(f.stop_exposure) + " stops" : "") })));
      }
      section.appendChild(grid);
    }
    if (diffs.length) {
      section.appendChild(el("h3", { text: "Signed difference to the reference" }));
      const grid = el("div", { class: "grid diffs" });
      for (const e of diffs) grid.appendChild(box(st, e, index++, onPixel));
      const scale = scene.difference_scale;
      if (scale && D.difference_colorbar) {
        grid.appendChild(el("div", { class: "legend" },
          el("div", { class: "legend-title", text: "(x̄ − r̄) / √(r̄² + 0.01) of the image shown above (linear scale, symmetric, shared by all methods)" }),
          el("img", { src: D.difference_colorbar, alt: "diverging colour scale" }),
          el("div", { class: "legend-ticks" },
            el("span", { text: fmt(-scale.max_abs), "data-key": view.slug + "/difference/min" }),
            el("span", { text: "0" }),
            el("span", { text: "+" + fmt(scale.max_abs), "data-key": view.slug + "/difference/max" })),
          el("div", { class: "legend-note", text: "blue = darker than the reference · orange = brighter · black = equal; x̄, r̄: channel means" })));
      }
      section.appendChild(grid);
    }

    // Tables full width, then the headline ratios beside the convergence plot.
    section.appendChild(el("h3", { text: "Error over " + scene.seeds + (scene.seeds === 1 ? " seed" : " seeds") }));
    section.appendChild(el("div", { class: "table-wrap" }, resultsTable(scene, view, main, ablations)));
    const provenance = provenanceBlock(scene);
    if (provenance) section.appendChild(provenance);
    const left = el("div", {});
    const ratios = view.ratios || [];
    if (ratios.length) {
      left.appendChild(el("h3", { text: "Ratios of mean relMSE" }));
      const ratioBox = el("div", { class: "ratios" });
      for (const r of ratios) {
        const key = view.slug + "/ratio/" + r.numerator + "/" + r.denominator;
        ratioBox.appendChild(el("div", { class: "ratio" },
          el("span", { class: "k", text: short(r.numerator) + " / " + short(r.denominator) }),
          el("span", { class: "v" },
            el("span", { text: fmt(r.value), "data-key": key }),
            r.se !== null && r.se !== undefined ? el("small", {}, " ± ", el("span", { text: fmt(r.se), "data-key": key + "/se" })) : null)));
      }
      left.appendChild(ratioBox);
      left.appendChild(el("p", { class: "note", text: "Below 1: " + short(ratios[0].numerator) + " has the lower error at equal total samples. ± is a delta-method standard error over paired seeds." }));
    }
    const right = el("div", { class: "plot" });
    right.appendChild(el("h3", { text: "Convergence" }));
    if (view.plot) {
      const plots = el("div", { class: "plots" }, el("img", { src: view.plot, alt: "relMSE against spp, log-log", "data-plot": "spp" }));
      if (view.time_plot) plots.appendChild(el("img", { src: view.time_plot, alt: "relMSE against seconds per image, log-log", "data-plot": "time" }));
      else plots.appendChild(el("div", { class: "none", text: "No times per point in these results (a study by an older cvtrace): rerun the study to plot relMSE against time." }));
      if (view.bias_plot) plots.appendChild(el("img", { src: view.bias_plot, alt: "squared bias against spp, log-log", "data-plot": "bias" }));
      right.appendChild(plots);
    } else right.appendChild(el("div", { class: "none", text: "No convergence data: run the study with an --spp list to plot relMSE against spp and against time." }));
    section.appendChild(el("div", { class: "columns" }, left, right));

    if (ablationPhotos.length) {
      const det = el("details", {}, el("summary", { text: "Ablation images (" + ablationPhotos.length + ")" }));
      const grid = el("div", { class: "grid ablations" });
      for (const e of ablationPhotos) grid.appendChild(box(st, e, index++, onPixel));
      det.appendChild(grid);
      det.addEventListener("toggle", () => apply(st));
      section.appendChild(det);
    }
    main_append(section);
    st.grids = [...section.querySelectorAll(".grid")];
    balanceGrids(st);

    // Initial view from the URL hash (applies to the named scene, or to all without a name).
    if (!hash.scene || hash.scene === view.slug) {
      if (hash.z !== null) st.z = hash.z;
      if (hash.cx !== null) st.cx = hash.cx;
      if (hash.cy !== null) st.cy = hash.cy;
      if (hash.ev !== null) { st.ev = Math.min(6, Math.max(-6, hash.ev)); setExposure(st.ev); }
    }
    apply(st);
    if (hash.flip !== null && (!hash.scene || hash.scene === view.slug) && st.entries[hash.flip - 1]) openFlip(st, hash.flip - 1);
  }
  function main_append(section) { main.appendChild(section); }

  // Columns that fill the rows evenly (8 boxes: 4 + 4, not 6 + 2); all grids of a scene
  // share the count so each relMSE map sits under its image.
  function balanceGrids(st) {
    if (!st.grids || !st.grids.length) return;
    const n = Math.max(...st.grids.filter((g) => !g.classList.contains("ablations")).map((g) => g.children.length), 1);
    const W = st.grids[0].clientWidth, gap = 10, minBox = 230;
    const maxCols = Math.max(1, Math.floor((W + gap) / (minBox + gap)));
    const cols = Math.ceil(n / Math.ceil(n / maxCols));
    for (const g of st.grids) g.style.gridTemplateColumns = "repeat(" + cols + ", minmax(0, 1fr))";
  }

  // What produced the numbers: every method's settings and diagnostics, and the renders'
  // provenance, folded away under the table.
  function provenanceBlock(scene) {
    const rows = scene.methods.filter((m) => (m.settings || []).length || (m.diagnostics || []).length);
    if (!rows.length && !(scene.render || []).length) return null;
    const pairs = (list) => list.map(([k, v]) => k + " = " + (typeof v === "number" ? fmt(v) : v)).join(", ");
    const table = el("table", { class: "results settings" });
    table.appendChild(el("thead", {}, el("tr", {}, el("th", { text: "Method" }), el("th", { text: "settings" }), el("th", { text: "diagnostics (mean over seeds)" }))));
    const body = el("tbody");
    for (const m of rows) body.appendChild(el("tr", { "data-method": m.name }, el("td", { text: m.label }), el("td", { text: pairs(m.settings || []) }), el("td", { text: pairs(m.diagnostics || []) })));
    table.appendChild(body);
    const details = el("details", { class: "provenance" }, el("summary", { text: "Settings, diagnostics and render provenance" }), table);
    if ((scene.render || []).length) details.appendChild(el("p", { class: "note", text: "Renders: " + pairs(scene.render) }));
    return details;
  }

  // The order of the results file, which is the order of the registry that wrote it.
  function orderedMethods(scene) {
    return scene.methods.slice();
  }

  // Main methods, then ablations under a group row, in one table so the columns line up.
  function resultsTable(scene, view, methods, ablations) {
    const pt2n = scene.methods.find((m) => m.name === "pt2n");
    const best = Math.min(...methods.map((m) => m.relmse_mean));
    const worst = Math.max(...methods.concat(ablations).map((m) => m.relmse_mean));
    // FLIP's columns only where some method has it (results of older studies do not).
    const hasFlip = methods.concat(ablations).some((m) => m.flip_mean !== null && m.flip_mean !== undefined);
    const head = ["Method", "spp", "relMSE", "± s.e.", "÷ PT(2n)", "bias²", "variance", "MSE"].concat(hasFlip ? ["FLIP", "FLIP ± s.e."] : [], ["render s", "recon s", "total s", "relMSE × s", "÷ PT(2n), equal time"]);
    const bestFlip = Math.min(...methods.map((m) => (m.flip_mean === null || m.flip_mean === undefined ? Infinity : m.flip_mean)));
    const titles = { FLIP: "HDR-FLIP: mean perceptual error in [0, 1] (NVIDIA's FLIP), mean over seeds", "relMSE × s": "equal-time efficiency: relMSE times the total seconds per image (lower is better)", "÷ PT(2n), equal time": "relMSE × s over PT(2n)'s: below 1, better than PT at equal time" };
    const table = el("table", { class: "results" });
    const tbody = el("tbody");
    // Click a header to sort the methods by it (again to reverse); ablations stay below.
    let sorted = { col: -1, dir: 1 };
    const sortBy = (col) => {
      sorted = { col, dir: sorted.col === col ? -sorted.dir : 1 };
      const main = Array.from(tbody.querySelectorAll("tr.main"));
      const value = (tr) => {
        const td = tr.children[col];
        const v = parseFloat(td.getAttribute("data-value"));
        return isNaN(v) ? (col === 0 ? td.textContent : Infinity) : v;
      };
      main.sort((a, b) => { const x = value(a), y = value(b); return (x < y ? -1 : x > y ? 1 : 0) * sorted.dir; });
      // Before the ablations' group row (or at the end): never before a row being moved.
      const after = [...tbody.children].find((tr) => !tr.classList.contains("main")) || null;
      for (const tr of main) tbody.insertBefore(tr, after);
    };
    table.appendChild(el("thead", {}, el("tr", {}, ...head.map((h, i) => el("th", { text: h, title: titles[h] || "click to sort", class: "sortable", onclick: () => sortBy(i) })))));
    const efficiency = (m) => { const t = m.time_seconds || {}; const s = (t.render || 0) + (t.reconstruct || 0); return s > 0 ? m.relmse_mean * s : null; };
    const pt2nEff = pt2n ? efficiency(pt2n) : null;
    const colors = view.colors || {};
    const rows = methods.map((m) => [m, false]).concat(ablations.map((m, i) => [m, i === 0]));
    for (const [m, groupStart] of rows) {
      if (groupStart) tbody.appendChild(el("tr", { class: "group" }, el("td", { colSpan: head.length, text: "Ablations" })));
      const k = (f) => view.slug + "/" + m.name + "/" + f;
      const rel = el("td", { class: "rel" + (m.relmse_mean === best ? " best" : ""), text: fmt(m.relmse_mean), "data-key": k("relmse_mean") });
      if (m.relmse_per_seed && m.relmse_per_seed.length) rel.title = "per seed: " + m.relmse_per_seed.map(fmt).join(", ");
      rel.appendChild(el("span", { class: "bar", style: "width:calc((100% - 12px) * " + (worst > 0 ? m.relmse_mean / worst : 0) + ");background:" + (colors[m.name] || "#888") }));
      const t = m.time_seconds || { render: null, reconstruct: null };
      const eff = efficiency(m);
      const cells = [
        [el("td", {}, el("span", { class: "swatch", style: "background:" + (colors[m.name] || "#888") + ";margin-right:7px" }), m.label), null],
        [el("td", { class: "dim", text: m.spp_total ? String(m.spp_total) : "?" }), m.spp_total],
        [rel, m.relmse_mean],
        [el("td", { class: "dim", text: fmt(m.relmse_se), "data-key": k("relmse_se") }), m.relmse_se],
        [el("td", { text: pt2n && pt2n.relmse_mean > 0 ? fmt(m.relmse_mean / pt2n.relmse_mean) : "–", "data-key": k("over_pt2n") }), pt2n && pt2n.relmse_mean > 0 ? m.relmse_mean / pt2n.relmse_mean : null],
        [el("td", { text: fmt(m.bias2), "data-key": k("bias2") }), m.bias2],
        [el("td", { text: fmt(m.variance), "data-key": k("variance") }), m.variance],
        [el("td", { text: fmt(m.mse_mean), "data-key": k("mse_mean") }), m.mse_mean],
      ].concat(hasFlip ? [
        [el("td", { class: m.flip_mean === bestFlip ? "best" : null, text: fmt(m.flip_mean), "data-key": k("flip_mean"), title: (m.flip_per_seed || []).length ? "per seed: " + m.flip_per_seed.map(fmt).join(", ") : null }), m.flip_mean],
        [el("td", { class: "dim", text: fmt(m.flip_se), "data-key": k("flip_se") }), m.flip_se],
      ] : [], [
        [el("td", { text: fmtSec(t.render), "data-key": k("time_render") }), t.render],
        [el("td", { text: fmtSec(t.reconstruct), "data-key": k("time_reconstruct") }), t.reconstruct],
        [el("td", { text: fmtSec(t.render + t.reconstruct), "data-key": k("time_total") }), t.render + t.reconstruct],
        [el("td", { text: eff === null ? "–" : fmt(eff), "data-key": k("efficiency") }), eff],
        [el("td", { text: eff !== null && pt2nEff ? fmt(eff / pt2nEff) : "–", "data-key": k("efficiency_over_pt2n") }), eff !== null && pt2nEff ? eff / pt2nEff : null],
      ]);
      for (const [td, v] of cells) if (v !== null && v !== undefined && isFinite(v)) td.setAttribute("data-value", String(v));
      tbody.appendChild(el("tr", { "data-method": m.name, class: m.ablation ? "ablation" : "main" }, ...cells.map(([td]) => td)));
    }
    table.appendChild(tbody);
    return table;
  }

  // ---- flip view: one large viewport, methods switched in place -----------------------------
  const flip = document.getElementById("flip");
  const flipVp = document.getElementById("flip-viewport");
  const flipButtons = document.getElementById("flip-buttons");
  const flipTitle = document.getElementById("flip-title");
  let flipState = null, flipIndex = 0;
  function showFlip(i) {
    const st = flipState;
    flipIndex = (i + st.entries.length) % st.entries.length;
    const e = st.entries[flipIndex];
    flipVp.classList.toggle("photo", e.photo);
    let img = flipVp.querySelector("img");
    if (!img) { img = el("img", { draggable: false }); flipVp.appendChild(img); }
    img.src = e.src;
    img.alt = e.label;
    flipTitle.textContent = st.scene.name + " — " + e.label + (e.kind === "relmse" ? " (relMSE map)" : e.kind === "flip" ? " (HDR-FLIP map)" : e.kind === "diff" ? " (difference to the reference)" : "");
    if (st.pixel) flipShowPixel(st, st.pixel[0], st.pixel[1]);
    [...flipButtons.children].forEach((b, k) => b.classList.toggle("on", k === flipIndex));
    layout(flipVp, st);
  }
  // The flip view's one-line readout: the shown image's values at the pixel.
  const flipReadout = document.getElementById("flip-readout");
  function flipShowPixel(st, x, y) {
    if (!flipReadout || flipState !== st) return;
    const e = st.entries[flipIndex];
    const v = st.pixelAt ? st.pixelAt(x, y, e.key) : null;
    flipReadout.textContent = "(" + x + ", " + y + ")" + (v ? " · RGB " + v.rgb.map(fmt).join(" ") + (v.relmse !== null ? " · relMSE " + fmt(v.relmse) : "") + (v.flip !== null ? " · FLIP " + fmt(v.flip) : "") : "");
  }
  function openFlip(st, i) {
    st.flipReadout = (x, y) => flipShowPixel(st, x, y);
    if (flipState !== st) {
      if (flipState) flipState.viewports.delete(flipVp);
      flipState = st;
      flipButtons.textContent = "";
      st.entries.forEach((e, k) => {
        const b = el("button", { type: "button", text: (k < 9 ? k + 1 + " " : "") + e.label + (e.kind === "relmse" ? " map" : e.kind === "flip" ? " FLIP" : e.kind === "diff" ? " diff" : "") });
        b.addEventListener("click", () => showFlip(k));
        flipButtons.appendChild(b);
      });
    }
    flip.classList.remove("hidden");
    st.viewports.add(flipVp);
    showFlip(i);
  }
  function closeFlip() {
    flip.classList.add("hidden");
    if (flipState) flipState.viewports.delete(flipVp);
  }
  // The flip viewport's interaction follows whichever scene it shows.
  (function wireFlip() {
    const proxy = { get: () => flipState };
    let drag = null;
    flipVp.addEventListener("wheel", (ev) => {
      const st = proxy.get(); if (!st) return;
      ev.preventDefault();
      const [u, v, px, py, , , W, H] = imagePoint(flipVp, st, ev.clientX, ev.clientY);
      st.z = Math.min(Math.max(st.z * Math.pow(1.25, -Math.sign(ev.deltaY)), 1), zMax(st));
      const [fw, fh] = fitSize(flipVp, st);
      st.cx = u - (px - W / 2) / (fw * st.z);
      st.cy = v - (py - H / 2) / (fh * st.z);
      apply(st);
    }, { passive: false });
    // Hover or tap: the readout of the pixel, here and in the scene's table.
    const report = (ev) => {
      const st = proxy.get(); if (!st) return;
      const [u, v] = imagePoint(flipVp, st, ev.clientX, ev.clientY);
      if (!(u >= 0 && u < 1 && v >= 0 && v < 1)) return;
      const x = Math.floor(u * st.scene.width), y = Math.floor(v * st.scene.height);
      st.pixel = [x, y];
      if (st.onPixel) st.onPixel(x, y, st.entries[flipIndex].key);
      flipShowPixel(st, x, y);
    };
    flipVp.addEventListener("pointerdown", (ev) => { report(ev); drag = { x: ev.clientX, y: ev.clientY }; flipVp.setPointerCapture(ev.pointerId); });
    flipVp.addEventListener("pointermove", (ev) => {
      report(ev);
      const st = proxy.get(); if (!st || !drag) return;
      const [fw, fh] = fitSize(flipVp, st);
      st.cx -= (ev.clientX - drag.x) / (fw * st.z);
      st.cy -= (ev.clientY - drag.y) / (fh * st.z);
      drag = { x: ev.clientX, y: ev.clientY };
      apply(st);
    });
    flipVp.addEventListener("pointerup", () => { drag = null; if (flipState) saveHash(flipState); });
  })();
  document.addEventListener("keydown", (ev) => {
    if (flip.classList.contains("hidden") || !flipState) return;
    if (ev.key === "Escape") closeFlip();
    else if (ev.key === "ArrowRight") showFlip(flipIndex + 1);
    else if (ev.key === "ArrowLeft") showFlip(flipIndex - 1);
    else if (/^[1-9]$/.test(ev.key) && Number(ev.key) <= flipState.entries.length) showFlip(Number(ev.key) - 1);
    else return;
    ev.preventDefault();
  });

  // ---- page ------------------------------------------------------------------------------------
  document.title = (D.title || "cvtrace") + " — estimator comparison";
  document.getElementById("generator").textContent = [D.results.generator, D.files && D.files.json ? "" : null].filter(Boolean).join(" ");
  if (D.files) {
    const g = document.getElementById("generator");
    for (const [name, href] of Object.entries(D.files)) g.append(" · ", el("a", { class: "dl", href, text: name }));
  }
  const nav = document.getElementById("scene-nav");
  D.results.scenes.forEach((scene, i) => {
    const view = D.scenes[i];
    nav.appendChild(el("a", { href: "#", text: scene.name, onclick: (ev) => { ev.preventDefault(); document.getElementById(view.slug).scrollIntoView(); } }));
    buildScene(scene, view);
  });
  if ((D.geomean_ratios || []).length && D.results.scenes.length > 1) {
    const box = el("div", { class: "ratios row" });
    for (const r of D.geomean_ratios) {
      const key = "geomean/" + r.numerator + "/" + r.denominator;
      box.appendChild(el("div", { class: "ratio" }, el("span", { class: "k", text: "geomean " + short(r.numerator) + " / " + short(r.denominator) }),
        el("span", { class: "v" },
          el("span", { text: fmt(r.value), "data-key": key }),
          r.se !== null && r.se !== undefined ? el("small", {}, " ± ", el("span", { text: fmt(r.se), "data-key": key + "/se" })) : null)));
    }
    main.appendChild(el("section", { class: "scene" }, el("h2", { text: "All scenes (geometric mean)" }), box));
  }
  window.addEventListener("resize", () => { states.forEach((st) => { balanceGrids(st); apply(st); }); if (flipState && !flip.classList.contains("hidden")) layout(flipVp, flipState); });

  // ---- load accounting: body[data-loaded="ok/total"], data-ready once all settled -----------
  const imgs = [...document.querySelectorAll("img")];
  let ok = 0, failed = 0;
  const failedSrc = [];
  function settle() {
    body.dataset.loaded = ok + "/" + imgs.length;
    body.dataset.failed = String(failed);
    if (failedSrc.length) body.dataset.failedSrc = failedSrc.join(" ");
    if (ok + failed === imgs.length) body.dataset.ready = "1";
  }
  for (const img of imgs) {
    const done = () => {
      if (img.dataset.counted) return;
      img.dataset.counted = "1";
      if (img.naturalWidth > 0) ok++; else { failed++; failedSrc.push(img.getAttribute("src")); }
      settle();
    };
    if (img.complete) done();
    else { img.addEventListener("load", done); img.addEventListener("error", done); }
  }
  settle();
})();
