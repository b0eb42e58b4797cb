#!/usr/bin/python3
"""Drives a report page (index.html of a results folder) in headless Chromium and checks it.

Run by tests/apps/report_page_test.cpp; by hand:

    /usr/bin/python3 tests/apps/report_page.py RESULTS_DIR [--shots DIR] [--chromium /usr/bin/chromium]

Talks the DevTools protocol over --remote-debugging-pipe (fds 3 and 4, NUL-separated JSON), so
it needs nothing beyond Python and Debian's chromium. Checks, each printed as "FAIL: ..." when it
does not hold (exit 1), against results.json rather than the page's own data:

  - a method with tiles worse than its input has them outlined (hiding them changes the view);
  - both image selectors of every scene list every image of the scene: the input, the reference,
    every method and variant record at the tables' spp and first seed, and each one's error maps;
  - choosing two other images changes the pixels of both sides of the split view;
  - a wheel event on one view changes the scale of every view of the scene (and to one scale),
    and a drag pans every view;
  - an error map on show has a colour bar with tick labels;
  - number keys flip the right image; the loupe shows both sides' values;
  - at 800 and 1400 px wide no table is wider than the viewport unless inside a scroll box,
    and the page itself does not scroll sideways (screenshots written with --shots);
  - no console error or warning, no uncaught exception, no failed request, in the whole run;
  - a sequence (results.json's config.sequences) is one viewer, not one per frame: its frame
    slider, the next-frame button and the comma key go to another frame, whose selectors list
    that frame's images (against results.json), and the two chosen images stay the same method
    and kind while the pixels and the heading change to that frame's.
"""
import argparse
import base64
import fcntl
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

FAILS = []
WORSE = {}  # scene -> {method: number of worse tiles}, from results.json (main)


def fail(msg):
    FAILS.append(msg)
    print("FAIL: " + msg, flush=True)


class Chromium:
    def __init__(self, exe, profile):
        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()
        hi_r = fcntl.fcntl(to_child_r, fcntl.F_DUPFD, 10)
        hi_w = fcntl.fcntl(from_child_w, fcntl.F_DUPFD, 10)

        def child_fds():
            os.dup2(hi_r, 3)
            os.dup2(hi_w, 4)

        args = [exe, "--headless=new", "--remote-debugging-pipe", "--no-sandbox", "--disable-gpu",
                "--disable-background-networking", "--no-first-run", "--disable-component-update", "--disable-sync",
                "--disable-extensions", "--user-data-dir=" + profile, "about:blank"]
        self.proc = subprocess.Popen(args, preexec_fn=child_fds, pass_fds=(3, 4, hi_r, hi_w),
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for fd in (to_child_r, from_child_w, hi_r, hi_w):
            os.close(fd)
        self.w = to_child_w
        self.r = from_child_r
        self.buf = b""
        self.next_id = 0
        self.events = []
        self.session = None

    def _read_message(self, deadline):
        while b"\0" not in self.buf:
            if time.time() > deadline:
                raise TimeoutError("no answer from chromium")
            chunk = os.read(self.r, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the pipe")
            self.buf += chunk
        msg, self.buf = self.buf.split(b"\0", 1)
        return json.loads(msg)

    def send(self, method, params=None, session=True, timeout=30):
        self.next_id += 1
        mid = self.next_id
        msg = {"id": mid, "method": method, "params": params or {}}
        if session and self.session:
            msg["sessionId"] = self.session
        os.write(self.w, json.dumps(msg).encode() + b"\0")
        deadline = time.time() + timeout
        while True:
            m = self._read_message(deadline)
            if m.get("id") == mid:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self.events.append(m)

    def wait_event(self, method, timeout=30):
        deadline = time.time() + timeout
        for i, e in enumerate(self.events):
            if e.get("method") == method:
                return self.events.pop(i)
        while True:
            m = self._read_message(deadline)
            if m.get("method") == method:
                return m
            self.events.append(m)

    def eval(self, expr, timeout=30):
        r = self.send("Runtime.evaluate", {"expression": expr, "returnByValue": True, "awaitPromise": True}, timeout=timeout)
        if "exceptionDetails" in r:
            raise RuntimeError(f"page script failed: {r['exceptionDetails'].get('exception', {}).get('description', r)}")
        return r["result"].get("value")

    def close(self):
        try:
            self.send("Browser.close", session=False, timeout=5)
        except Exception:
            pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def expected_images(results_dir):
    """(scene -> sorted list of (method, kind))) from results.json, as the page must list them."""
    with open(os.path.join(results_dir, "results.json")) as f:
        res = json.load(f)
    cfg = res["config"]
    spp = cfg["spp"][0]
    seed = (cfg.get("seeds") or [None])[0]
    out = {}
    for r in res["records"]:
        if r.get("role") == "plain" or r["spp"] != spp or not r.get("files", {}).get("image"):
            continue
        if seed is not None and r.get("seed") not in (None, seed):
            continue
        lst = out.setdefault(r["scene"], [("reference", "radiance")])
        lst.append((r["method"], "radiance"))
        for k, kind in (("error_flip", "flip"), ("error_hdrflip", "hdrflip"), ("error_relmse", "relmse")):
            if r["files"].get(k):
                lst.append((r["method"], kind))
    return {s: sorted(v) for s, v in out.items()}


def sequence_rows(results_dir):
    """(sequence name -> its frame rows in order) from results.json's config (name.fNN)."""
    with open(os.path.join(results_dir, "results.json")) as f:
        cfg = json.load(f)["config"]
    return {n: [f"{n}.f{t:02d}" for t in range(int(k))] for n, k in (cfg.get("sequences") or {}).items()}


def worse_tile_counts(results_dir):
    """(scene -> {method: number of worse_tiles}) from results.json, at the page's spp and seed."""
    with open(os.path.join(results_dir, "results.json")) as f:
        res = json.load(f)
    cfg = res["config"]
    spp, seed = cfg["spp"][0], (cfg.get("seeds") or [None])[0]
    out = {}
    for r in res["records"]:
        if r.get("role") in ("method", "ablation") and r["spp"] == spp and r.get("worse_tiles") and \
                (seed is None or r.get("seed") in (None, seed)):
            out.setdefault(r["scene"], {})[r["method"]] = len(r["worse_tiles"])
    return out


# Page-side helpers: a digest of a canvas region, each scene's state.
HELPERS = r"""
window.__t = {
  digest: function (canvas, x0, x1) {
    // Read through a copy: the view's own canvas is drawn to, not read from (Chromium warns on
    // repeated readbacks of one canvas).
    var w = canvas.width, h = canvas.height, copy = document.createElement('canvas');
    copy.width = w; copy.height = h;
    var ctx = copy.getContext('2d', {willReadFrequently: true});
    ctx.drawImage(canvas, 0, 0);
    var d = ctx.getImageData(Math.floor(x0 * w), 0, Math.max(1, Math.floor((x1 - x0) * w)), h).data, s = 0;
    for (var i = 0; i < d.length; i += 4) s = (s * 31 + d[i] * 7 + d[i + 1] * 3 + d[i + 2]) % 1000000007;
    return s;
  },
  scenes: function () { return Array.prototype.map.call(document.querySelectorAll('section.scene'), function (s) {
    return {name: s.dataset.scene, views: Array.prototype.map.call(s.querySelectorAll('canvas.view-canvas'), function (c) {
      var r = c.getBoundingClientRect();
      return {scale: c.dataset.scale, cx: c.dataset.cx, cy: c.dataset.cy, x: r.left, y: r.top, w: r.width, h: r.height}; })};
  }); },
  ready: function () { return window.dnbViewer && window.dnbViewer.scenes.every(function (sc) {
    return Array.prototype.every.call(sc.section.querySelectorAll('canvas.view-canvas'), function (c) { return !!c.dataset.scale; })
      && sc.entries().left._img && sc.entries().right._img && sc.entries().second._img; }); },
  settled: function () { return new Promise(function (ok) { setTimeout(function () {
    requestAnimationFrame(function () { requestAnimationFrame(function () { ok(true); }); }); }, 150); }); }
};
true
"""


def wait_ready(ch, what, timeout=20):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if ch.eval("window.__t && window.__t.ready()"):
            ch.eval("window.__t.settled()")
            return True
        time.sleep(0.1)
    fail(f"the viewer did not draw every view ({what}) within {timeout} s")
    return False


def check_selectors(ch, expected):
    got = ch.eval("""Array.prototype.map.call(document.querySelectorAll('section.scene'), function (s) {
      function opts(sel) { return Array.prototype.map.call(s.querySelectorAll(sel + ' option'), function (o) {
        return [o.dataset.method, o.dataset.kind]; }); }
      return {name: s.dataset.scene, left: opts('select.pick-left'), right: opts('select.pick-right')}; })""")
    names = [g["name"] for g in got]
    if sorted(names) != sorted(expected):
        fail(f"scenes on the page {names}, results.json has {sorted(expected)}")
    for g in got:
        want = expected.get(g["name"], [])
        for side in ("left", "right"):
            have = sorted(tuple(x) for x in g[side])
            if have != [tuple(w) for w in want]:
                fail(f"{g['name']}: the {side} selector lists {have}, results.json has {want}")
    return got


def choose(ch, scene_i, side, method, kind):
    return ch.eval(f"""(function () {{
      var s = document.querySelectorAll('section.scene')[{scene_i}], sel = s.querySelector('select.pick-{side}');
      for (var i = 0; i < sel.options.length; i++)
        if (sel.options[i].dataset.method === {json.dumps(method)} && sel.options[i].dataset.kind === {json.dumps(kind)}) {{
          sel.value = sel.options[i].value; sel.dispatchEvent(new Event('change')); return true; }}
      return false; }})()""")


def split_digests(ch, scene_i):
    return ch.eval(f"""(function () {{ var c = document.querySelectorAll('section.scene')[{scene_i}].querySelector('.view-split canvas');
      return [window.__t.digest(c, 0.02, 0.45), window.__t.digest(c, 0.55, 0.98)]; }})()""")


def check_viewer(ch, expected):
    scenes = ch.eval("window.__t.scenes()")
    for i, sc in enumerate(scenes):
        name = sc["name"]
        want = expected.get(name, [])
        methods = [m for m, k in want if k == "radiance" and m not in ("input", "reference")]
        ch.eval(f"document.querySelectorAll('section.scene')[{i}].scrollIntoView()")
        ch.eval("window.__t.settled()")
        # Two other images: the input on the left, a FLIP map on the right.
        before = split_digests(ch, i)
        labels0 = ch.eval(f"Array.prototype.map.call(document.querySelectorAll('section.scene')[{i}].querySelectorAll('.view-split .label'), function (l) {{ return l.textContent; }})")
        flip_of = methods[0] if methods else "input"
        if not choose(ch, i, "left", "input", "radiance") or not choose(ch, i, "right", flip_of, "flip"):
            fail(f"{name}: cannot choose the input and {flip_of}'s FLIP map")
            continue
        wait_ready(ch, name)
        after = split_digests(ch, i)
        labels1 = ch.eval(f"Array.prototype.map.call(document.querySelectorAll('section.scene')[{i}].querySelectorAll('.view-split .label'), function (l) {{ return l.textContent; }})")
        if after[0] == before[0]:
            fail(f"{name}: choosing the input on the left did not change the left side's pixels")
        if after[1] == before[1]:
            fail(f"{name}: choosing a FLIP map on the right did not change the right side's pixels")
        if labels1 == labels0 or "input" not in labels1[0] or "FLIP" not in labels1[1]:
            fail(f"{name}: the split view's labels {labels0} -> {labels1} do not name the chosen images")
        # The error map's colour bar.
        bar = ch.eval(f"""(function () {{ var b = document.querySelectorAll('section.scene')[{i}].querySelector('.colourbar[data-kind=flip]');
          if (!b) return null; var c = b.querySelector('canvas'), d = c.getContext('2d').getImageData(0, 0, c.width, 1).data;
          return {{w: b.offsetWidth, ticks: b.querySelectorAll('.ticks span').length, caption: b.textContent,
                   ends: [d[0], d[1], d[2], d[d.length - 4], d[d.length - 3], d[d.length - 2]]}}; }})()""")
        if not bar or bar["w"] <= 0 or bar["ticks"] < 2 or bar["ends"][:3] == bar["ends"][3:]:
            fail(f"{name}: a FLIP map on show but no visible colour bar with a scale ({bar})")
        # Zoom: a wheel over the split view scales every view of the scene alike.
        v = ch.eval("window.__t.scenes()")[i]["views"]
        x, y = v[0]["x"] + v[0]["w"] * 0.3, v[0]["y"] + v[0]["h"] * 0.4
        ch.send("Input.dispatchMouseEvent", {"type": "mouseWheel", "x": x, "y": y, "deltaX": 0, "deltaY": -300})
        ch.eval("window.__t.settled()")
        v2 = ch.eval("window.__t.scenes()")[i]["views"]
        for k, (a, b) in enumerate(zip(v, v2)):
            if a["scale"] == b["scale"]:
                fail(f"{name}: a wheel event on the split view left view {k}'s scale at {a['scale']}")
        if len({b["scale"] for b in v2}) != 1:
            fail(f"{name}: after zooming the views have different scales {[b['scale'] for b in v2]}")
        # Pan: a drag away from the handle moves every view.
        sx, sy = v2[0]["x"] + v2[0]["w"] * 0.2, v2[0]["y"] + v2[0]["h"] * 0.5
        ch.send("Input.dispatchMouseEvent", {"type": "mousePressed", "x": sx, "y": sy, "button": "left", "clickCount": 1})
        ch.send("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": sx + 40, "y": sy + 20, "button": "left", "buttons": 1})
        ch.send("Input.dispatchMouseEvent", {"type": "mouseReleased", "x": sx + 40, "y": sy + 20, "button": "left", "clickCount": 1})
        ch.eval("window.__t.settled()")
        v3 = ch.eval("window.__t.scenes()")[i]["views"]
        for k, (a, b) in enumerate(zip(v2, v3)):
            if (a["cx"], a["cy"]) == (b["cx"], b["cy"]):
                fail(f"{name}: dragging did not pan view {k}")
        # The loupe: both sides' values under the pointer.
        ch.send("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": v3[0]["x"] + v3[0]["w"] * 0.5 + 30, "y": v3[0]["y"] + v3[0]["h"] * 0.5})
        loupe = ch.eval(f"""(function () {{ var l = document.querySelectorAll('section.scene')[{i}].querySelector('.loupe');
          return {{hidden: l.hidden, values: Array.prototype.map.call(l.querySelectorAll('.loupe-value'), function (e) {{ return e.textContent; }})}}; }})()""")
        if loupe["hidden"] or len(loupe["values"]) != 2:
            fail(f"{name}: the loupe does not show both sides' values ({loupe})")
        # Keys: "2" puts the scene's second image on the right, also after a selector had the
        # focus and the user clicked the view.
        ch.eval(f"document.querySelectorAll('section.scene')[{i}].querySelector('select.pick-right').focus()")
        cx, cy = v3[0]["x"] + v3[0]["w"] * 0.25, v3[0]["y"] + v3[0]["h"] * 0.5
        ch.send("Input.dispatchMouseEvent", {"type": "mousePressed", "x": cx, "y": cy, "button": "left", "clickCount": 1})
        ch.send("Input.dispatchMouseEvent", {"type": "mouseReleased", "x": cx, "y": cy, "button": "left", "clickCount": 1})
        ch.send("Input.dispatchKeyEvent", {"type": "keyDown", "key": "2", "code": "Digit2", "text": "2", "windowsVirtualKeyCode": 50})
        ch.send("Input.dispatchKeyEvent", {"type": "keyUp", "key": "2", "code": "Digit2", "windowsVirtualKeyCode": 50})
        right = ch.eval(f"""(function () {{ var s = document.querySelectorAll('section.scene')[{i}];
          return [s.querySelector('select.pick-right').value, s.querySelector('select.pick-right').options[1].value]; }})()""")
        if right[0] != right[1]:
            fail(f"{name}: the key 2 did not put the second image on the right ({right})")
        # Exposure works on the radiance: +3 stops brightens the input on the left.
        ch.eval(f"""(function () {{ var e = document.querySelectorAll('section.scene')[{i}].querySelector('input.exposure');
          e.value = '3'; e.dispatchEvent(new Event('input')); }})()""")
        ch.eval("window.__t.settled()")
        wait_ready(ch, name)
        # The tiles where a method is worse than its input (results.json's worse_tiles) are
        # outlined on it, and the box hides them.
        for worse, count in sorted(WORSE.get(name, {}).items())[:1]:
            on_page = ch.eval(f"""(function () {{ var d = DNB_MANIFEST.scenes[{i}];
              for (var k = 0; k < d.images.length; k++) {{ var e = d.images[k];
                if (e.kind === 'radiance' && e.method === {json.dumps(worse)}) return (e.worse_tiles || []).length; }}
              return -1; }})()""")
            if on_page != count:
                fail(f"{name}: {worse} has {count} worse tiles in results.json, the page has {on_page}")
            # On both sides (a tile may lie on either side of the split), the whole image in view.
            if not choose(ch, i, "left", worse, "radiance") or not choose(ch, i, "right", worse, "radiance"):
                fail(f"{name}: cannot choose {worse} on both sides")
            ch.eval(f"document.querySelectorAll('section.scene')[{i}].querySelector('button.fit').click()")
            ch.eval("window.__t.settled()")
            wait_ready(ch, name)
            on = split_digests(ch, i)
            ch.eval(f"document.querySelectorAll('section.scene')[{i}].querySelector('input.worse-tiles').click()")
            ch.eval("window.__t.settled()")
            off = split_digests(ch, i)
            ch.eval(f"document.querySelectorAll('section.scene')[{i}].querySelector('input.worse-tiles').click()")
            ch.eval("window.__t.settled()")
            if on == off:
                fail(f"{name}: hiding the worse-than-input tiles of {worse} did not change the view")


def check_sequences(ch, expected, sequences):
    """Each sequence's viewer: the frame slider, the buttons and the keys step through its frames,
    keeping the chosen two images (method and kind) and showing that frame's."""
    got = ch.eval("""Array.prototype.map.call(document.querySelectorAll('section.scene'), function (s, i) {
      return {i: i, sequence: s.dataset.sequence || null, scene: s.dataset.scene, slider: !!s.querySelector('input.frame')}; })""")
    on_page = {g["sequence"]: g for g in got if g["sequence"]}
    for name, rows in sequences.items():
        g = on_page.get(name)
        if not g:
            fail(f"sequence {name}: no viewer section with data-sequence (sections: {got})")
            continue
        i = g["i"]
        if not g["slider"]:
            fail(f"sequence {name}: no frame slider")
            continue

        def state():
            return ch.eval(f"""(function () {{ var s = document.querySelectorAll('section.scene')[{i}];
              function pick(side) {{ var o = s.querySelector('select.pick-' + side).selectedOptions[0];
                return [o.dataset.method, o.dataset.kind]; }}
              return {{scene: s.dataset.scene, frame: s.dataset.frame, left: pick('left'), right: pick('right'),
                       heading: s.querySelector('h3').textContent, slider: s.querySelector('input.frame').value}}; }})()""")

        methods = [m for m, k in expected.get(rows[0], []) if k == "radiance" and m not in ("input", "reference")]
        left = methods[-1] if methods else "input"
        if not choose(ch, i, "left", left, "radiance") or not choose(ch, i, "right", "reference", "radiance"):
            fail(f"sequence {name}: cannot choose {left} and the reference")
            continue
        ch.eval(f"document.querySelectorAll('section.scene')[{i}].querySelector('button.fit').click()")
        wait_ready(ch, name)
        s0, d0 = state(), split_digests(ch, i)
        if s0["scene"] != rows[0]:
            fail(f"sequence {name}: opens on {s0['scene']}, not its first frame {rows[0]}")
        steps = [("slider", len(rows) - 1,
                  f"(function () {{ var e = document.querySelectorAll('section.scene')[{i}].querySelector('input.frame');"
                  f" e.value = '{len(rows) - 1}'; e.dispatchEvent(new Event('input')); }})()")]
        if len(rows) > 2:
            steps.append(("comma key", len(rows) - 2, None))
            steps.append(("next button", len(rows) - 1,
                          f"document.querySelectorAll('section.scene')[{i}].querySelector('button.frame-next').click()"))
        before = (s0, d0)
        for how, t, expr in steps:
            if expr:
                ch.eval(expr)
            else:
                ch.eval(f"document.querySelectorAll('section.scene')[{i}].focus()")
                ch.send("Input.dispatchKeyEvent", {"type": "keyDown", "key": ",", "code": "Comma", "text": ",",
                                                   "windowsVirtualKeyCode": 188})
                ch.send("Input.dispatchKeyEvent", {"type": "keyUp", "key": ",", "code": "Comma", "windowsVirtualKeyCode": 188})
            ch.eval("window.__t.settled()")
            wait_ready(ch, f"{name} frame {t}")
            s1, d1 = state(), split_digests(ch, i)
            if s1["scene"] != rows[t] or s1["frame"] != str(t) or s1["slider"] != str(t):
                fail(f"sequence {name}: the {how} should show frame {t} ({rows[t]}), the viewer shows {s1}")
            if (s1["left"], s1["right"]) != ([left, "radiance"], ["reference", "radiance"]):
                fail(f"sequence {name}: the {how} changed the chosen images to {s1['left']} / {s1['right']}")
            if s1["heading"] == before[0]["heading"]:
                fail(f"sequence {name}: the heading did not change with the {how}: {s1['heading']}")
            if d1[0] == before[1][0] or d1[1] == before[1][1]:
                fail(f"sequence {name}: the {how} left a side of the split view's pixels as they were ({before[1]} -> {d1})")
            got_sel = ch.eval(f"""Array.prototype.map.call(document.querySelectorAll('section.scene')[{i}]
              .querySelectorAll('select.pick-left option'), function (o) {{ return [o.dataset.method, o.dataset.kind]; }})""")
            if sorted(tuple(x) for x in got_sel) != [tuple(w) for w in expected.get(rows[t], [])]:
                fail(f"sequence {name}, frame {t}: the selector lists {sorted(got_sel)}, results.json has {expected.get(rows[t])}")
            before = (s1, d1)


def check_widths(ch, width, shots):
    ch.send("Emulation.setDeviceMetricsOverride", {"width": width, "height": 900, "deviceScaleFactor": 1, "mobile": False})
    ch.eval("window.scrollTo(0, 0)")
    ch.eval("window.__t.settled()")
    r = ch.eval("""(function () { var vw = document.documentElement.clientWidth, bad = [];
      document.querySelectorAll('table').forEach(function (t) {
        var box = t.closest('.table-scroll'), rt = t.getBoundingClientRect();
        var title = (t.closest('div') && t.closest('div').previousElementSibling || {}).textContent || t.className;
        if (rt.width <= vw + 0.5 && rt.right <= vw + 0.5) return;
        if (!box) { bad.push(title + ': ' + Math.round(rt.width) + ' px, no scroll box'); return; }
        var rb = box.getBoundingClientRect(), ox = getComputedStyle(box).overflowX;
        if (rb.right > vw + 0.5 || (ox !== 'auto' && ox !== 'scroll') || box.scrollWidth <= box.clientWidth)
          bad.push(title + ': ' + Math.round(rt.width) + ' px in a box of ' + Math.round(rb.width) + ' px, overflow ' + ox);
      });
      return {vw: vw, page: document.documentElement.scrollWidth, bad: bad, tables: document.querySelectorAll('table').length}; })()""")
    if r["tables"] == 0:
        fail(f"{width} px: no table on the page")
    for b in r["bad"]:
        fail(f"{width} px: a table wider than the viewport without a scroll bar: {b}")
    if r["page"] > r["vw"] + 1:
        fail(f"{width} px: the page is {r['page']} px wide, wider than the viewport ({r['vw']} px)")
    if shots:
        for name, expr in (("top", "window.scrollTo(0, 0)"), ("images", "document.getElementById('images').scrollIntoView()")):
            ch.eval(expr)
            ch.eval("window.__t.settled()")
            shot(ch, os.path.join(shots, f"page_{width}_{name}.png"))
    return r


def shot(ch, path):
    png = ch.send("Page.captureScreenshot", {"format": "png"})["data"]
    with open(path, "wb") as f:
        f.write(base64.b64decode(png))


def check_events(events):
    for e in events:
        m, p = e.get("method"), e.get("params", {})
        if m == "Runtime.exceptionThrown":
            fail("uncaught exception: " + json.dumps(p.get("exceptionDetails", {}))[:400])
        elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "warning", "assert"):
            fail("console " + p["type"] + ": " + json.dumps(p.get("args", []))[:400])
        elif m == "Log.entryAdded" and p.get("entry", {}).get("level") in ("error", "warning"):
            fail("log " + p["entry"]["level"] + ": " + p["entry"].get("text", "") + " " + p["entry"].get("url", ""))
        elif m == "Network.loadingFailed":
            if p.get("type") == "Media" and p.get("canceled"):
                continue  # a <video> reads what it needs of the file and cancels the rest: not a failure
            fail("failed request: " + json.dumps(p)[:400])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("results_dir")
    ap.add_argument("--shots", default="")
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    a = ap.parse_args()
    results_dir = os.path.abspath(a.results_dir)
    expected = expected_images(results_dir)
    sequences = sequence_rows(results_dir)
    # A sequence is one section on the page, opening on its first frame.
    later = {r for rows in sequences.values() for r in rows[1:]}
    sections = {k: v for k, v in expected.items() if k not in later}
    WORSE.update(worse_tile_counts(results_dir))
    if a.shots:
        os.makedirs(a.shots, exist_ok=True)
    profile = tempfile.mkdtemp(prefix="dnb-chromium-")
    ch = Chromium(a.chromium, profile)
    try:
        target = ch.send("Target.createTarget", {"url": "about:blank"}, session=False)["targetId"]
        ch.session = ch.send("Target.attachToTarget", {"targetId": target, "flatten": True}, session=False)["sessionId"]
        for d in ("Runtime.enable", "Log.enable", "Network.enable", "Page.enable"):
            ch.send(d)
        ch.send("Emulation.setDeviceMetricsOverride", {"width": 1400, "height": 900, "deviceScaleFactor": 1, "mobile": False})
        ch.send("Page.navigate", {"url": "file://" + results_dir + "/index.html"})
        ch.wait_event("Page.loadEventFired")
        ch.eval(HELPERS)
        if wait_ready(ch, "after loading"):
            if a.shots:  # the first scene as it opens, then with the pointer on it (the loupe)
                ch.eval("document.querySelector('section.scene').scrollIntoView()")
                ch.eval("window.__t.settled()")
                shot(ch, os.path.join(a.shots, "scene_1400_open.png"))
                v = ch.eval("window.__t.scenes()")[0]["views"][0]
                ch.send("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": v["x"] + v["w"] * 0.3, "y": v["y"] + v["h"] * 0.6})
                ch.eval("window.__t.settled()")
                shot(ch, os.path.join(a.shots, "scene_1400_loupe.png"))
            check_selectors(ch, sections)
            check_viewer(ch, sections)
            check_sequences(ch, expected, sequences)
        for w in (800, 1400):
            check_widths(ch, w, a.shots)
        ch.eval("window.__t.settled()")
        check_events(ch.events)
    finally:
        ch.close()
        shutil.rmtree(profile, ignore_errors=True)
    print(f"{len(FAILS)} failure(s)" if FAILS else "report page: every check passed")
    sys.exit(1 if FAILS else 0)


if __name__ == "__main__":
    main()
