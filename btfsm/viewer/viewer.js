/* btfsm viewer (btfsm/html.py inlines this file into every page). It reads the page's
   data (runs of neutral per-tick records, see btfsm/html.py) and colours the inlined
   Graphviz drawings; it fetches nothing. */
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("btfsm-data").textContent);
  var runs = data.runs;
  var cur = { run: 0, tick: 0 };
  var $ = function (id) { return document.getElementById(id); };
  var slider = $("slider");

  function esc(s) {
    return String(s).replace(/[&<>"]/g, function (c) { return { "&": "&amp;", "<": "&lt;", ">": "&gt;", "\"": "&quot;" }[c]; });
  }
  function val(v) { return v === null ? "none" : String(v); }

  // ------------------------------------------------------------------ drawings: index, zoom and pan
  function index(svg) {
    var map = {};
    svg.querySelectorAll("g[data-k]").forEach(function (g) {
      var k = g.getAttribute("data-k");
      (map[k] = map[k] || []).push(g);
    });
    return map;
  }
  var treeSvg = document.querySelector(".tree svg");
  var treeNodes = {};
  if (treeSvg) {
    var all = index(treeSvg);
    Object.keys(all).forEach(function (k) {
      if (k.indexOf("n:") === 0) { treeNodes[k.slice(2)] = all[k]; }
    });
  }
  var fsmPanels = [];
  document.querySelectorAll("section.fsm").forEach(function (sec) {
    var views = [];
    sec.querySelectorAll(".view").forEach(function (v) {
      var svg = v.querySelector("svg");
      views.push({ el: v, svg: svg, map: index(svg), kind: v.getAttribute("data-view") });
    });
    views.forEach(function (v, i) { v.el.hidden = i !== 0; });
    var panel = { name: sec.getAttribute("data-fsm"), sec: sec, views: views, shown: 0 };
    var toggle = sec.querySelector(".toggle");
    if (toggle) {
      toggle.addEventListener("click", function () {
        panel.shown = 1 - panel.shown;
        views.forEach(function (v, i) { v.el.hidden = i !== panel.shown; });
        toggle.textContent = views[panel.shown].kind === "full" ? "visited states only" : "whole FSM";
        fit(views[panel.shown].svg);
        size(sec.querySelector(".graph"));
        show();
      });
    }
    fsmPanels.push(panel);
  });

  function box(svg) {
    var vb = svg.getAttribute("viewBox").split(/[ ,]+/).map(Number);
    return { x: vb[0], y: vb[1], w: vb[2], h: vb[3] };
  }
  function setBox(svg, b) { svg.setAttribute("viewBox", [b.x, b.y, b.w, b.h].join(" ")); }
  function fit(svg) {
    if (!svg) { return; }
    if (!svg.dataset.home) { svg.dataset.home = svg.getAttribute("viewBox"); }
    svg.setAttribute("viewBox", svg.dataset.home);
  }
  document.querySelectorAll(".graph").forEach(function (graph) {
    var drag = null;
    function svgOf() { var v = graph.querySelector(".view:not([hidden]) svg"); return v; }
    graph.addEventListener("wheel", function (ev) {
      var svg = svgOf();
      if (!svg) { return; }
      ev.preventDefault();
      var b = box(svg), r = svg.getBoundingClientRect();
      var f = ev.deltaY < 0 ? 0.85 : 1 / 0.85;
      var px = b.x + (ev.clientX - r.left) / r.width * b.w, py = b.y + (ev.clientY - r.top) / r.height * b.h;
      setBox(svg, { x: px - (px - b.x) * f, y: py - (py - b.y) * f, w: b.w * f, h: b.h * f });
    }, { passive: false });
    graph.addEventListener("mousedown", function (ev) {
      var svg = svgOf();
      if (!svg) { return; }
      drag = { x: ev.clientX, y: ev.clientY, b: box(svg), svg: svg };
      graph.classList.add("dragging");
    });
    window.addEventListener("mousemove", function (ev) {
      if (!drag) { return; }
      var r = drag.svg.getBoundingClientRect();
      var sx = drag.b.w / r.width, sy = drag.b.h / r.height, s = Math.max(sx, sy);
      setBox(drag.svg, { x: drag.b.x - (ev.clientX - drag.x) * s, y: drag.b.y - (ev.clientY - drag.y) * s, w: drag.b.w, h: drag.b.h });
    });
    window.addEventListener("mouseup", function () { drag = null; graph.classList.remove("dragging"); });
    var btn = graph.parentNode.querySelector("button.fit");
    if (btn) { btn.addEventListener("click", function () { fit(svgOf()); }); }
    var near = graph.parentNode.querySelector("button.near");
    if (near) {
      near.addEventListener("click", function () {  // zoom in on the token's state
        var svg = svgOf(), g = svg && svg.querySelector("g.node.current");
        if (!g) { return; }
        var bb = g.getBBox(), home = svg.dataset.home.split(/[ ,]+/).map(Number);
        var w = Math.min(home[2], Math.max(bb.width * 4, home[2] / 4)), h = w * home[3] / home[2];
        var m = g.getCTM(), root = svg.getCTM();  // the node's box in the drawing's coordinates
        var pt = svg.createSVGPoint();
        pt.x = bb.x + bb.width / 2; pt.y = bb.y + bb.height / 2;
        var c = pt.matrixTransform(root.inverse().multiply(m));
        setBox(svg, { x: c.x - w / 2, y: c.y - h / 2, w: w, h: h });
      });
    }
  });
  document.querySelectorAll(".graph svg").forEach(fit);
  // each drawing's box as tall as its picture at the page's width (within 180 px .. 75 % of the window)
  function size(graph) {
    var svg = graph.querySelector(".view:not([hidden]) svg");
    if (!svg || !graph.clientWidth) { return; }
    var b = svg.dataset.home.split(/[ ,]+/).map(Number);
    var h = graph.clientWidth * b[3] / b[2] + 8;
    graph.style.height = Math.round(Math.max(180, Math.min(window.innerHeight * 0.75, h))) + "px";
  }
  function sizeAll() { document.querySelectorAll(".graph").forEach(size); }
  sizeAll();
  window.addEventListener("resize", sizeAll);

  // ------------------------------------------------------------------ verdicts and runs
  function verdicts() {
    var rows = data.verdicts.map(function (v) {
      var link = v.run === null || v.run === undefined ? "" :
        " <a data-run=\"" + v.run + "\">" + (runs[v.run] && runs[v.run].kind === "counterexample" ? "counterexample" : "show the run") + "</a>";
      return "<tr class=\"" + esc(v.cls || v.verdict.toLowerCase()) + "\" data-run=\"" + (v.run === null || v.run === undefined ? "" : v.run) +
        "\"><td>" + esc(v.name) + "</td><td class=\"v\">" + esc(v.verdict) + "</td><td>" + esc(v.summary || "") + link + "</td></tr>";
    });
    var notes = data.notes.map(function (n) { return "<div class=\"dim\">" + esc(n) + "</div>"; }).join("");
    $("verdicts").innerHTML = rows.length ? "<table><tr><th>property / run</th><th>verdict</th><th></th></tr>" + rows.join("") + "</table>" + notes : notes;
    $("verdicts").querySelectorAll("a[data-run]").forEach(function (a) {
      a.addEventListener("click", function () { selectRun(Number(a.getAttribute("data-run"))); });
    });
  }
  function runOptions() {
    var sel = $("run");
    sel.innerHTML = runs.map(function (r, i) { return "<option value=\"" + i + "\">" + esc(r.title) + "</option>"; }).join("");
    sel.addEventListener("change", function () { selectRun(Number(sel.value)); });
    if (!runs.length) {
      $("runbar").hidden = true;
    }
  }
  function strip(run) {
    var html = run.ticks.map(function (t, i) {
      var cls = "s-" + (t.status || "none");
      if (run.loop !== null && run.loop !== undefined) {
        if (i === run.loop + 1) { cls += " loop"; }
        if (i > run.loop) { cls += " incycle"; }
      }
      var title = "tick " + t.tick;
      (run.marks || []).forEach(function (m) { if (m[0] === i) { cls += " mark"; title += ": " + m[1]; } });
      return "<div class=\"" + cls + "\" data-t=\"" + i + "\" title=\"" + esc(title) + "\"></div>";
    });
    $("strip").innerHTML = html.join("");
  }
  $("strip").addEventListener("click", function (ev) {
    var t = ev.target.getAttribute("data-t");
    if (t !== null) { setTick(Number(t)); }
  });

  function selectRun(i) {
    if (!runs.length) { return; }
    cur.run = Math.max(0, Math.min(runs.length - 1, i));
    var run = runs[cur.run];
    $("run").value = String(cur.run);
    slider.max = String(run.ticks.length - 1);
    var parts = [esc(run.summary || "")];
    if (run.loop !== null && run.loop !== undefined) {
      parts.push("lasso: the cycle starts after tick " + run.loop + " and returns to the state after tick " + run.loop + " (marked on the timeline)");
    }
    (run.marks || []).forEach(function (m) { parts.push("<span class=\"note\">marked on the timeline: tick " + m[0] + ": " + esc(m[1]) + "</span>"); });
    if (run.note) { parts.push("<span class=\"note\">" + esc(run.note) + "</span>"); }
    if (run.violation) { parts.push(esc(run.violation)); }
    $("summary").innerHTML = parts.filter(Boolean).join("\n");
    document.querySelectorAll("#verdicts tr").forEach(function (tr) {
      tr.classList.toggle("selected", tr.getAttribute("data-run") === String(cur.run));
    });
    strip(run);
    markVisited(run);
    setTick(0);
  }
  function markVisited(run) {
    var seen = {};
    run.ticks.forEach(function (t) {
      Object.keys(t.fsm || {}).forEach(function (f) { (seen[f] = seen[f] || {})[t.fsm[f][0]] = true; });
    });
    fsmPanels.forEach(function (p) {
      p.views.forEach(function (v) {
        Object.keys(v.map).forEach(function (k) {
          if (k.indexOf("s:") === 0) {
            v.map[k].forEach(function (g) { g.classList.toggle("visited", !!(seen[p.name] || {})[k.slice(2)]); });
          }
        });
      });
    });
  }

  // ------------------------------------------------------------------ one tick
  function varsAt(run, i) {
    var out = {}, changed = {};
    Object.keys(run.initial || {}).forEach(function (k) { out[k] = run.initial[k]; });
    for (var j = 1; j <= i; j++) {
      var ch = run.ticks[j].changes || {};
      Object.keys(ch).forEach(function (k) { out[k] = ch[k]; if (j === i) { changed[k] = true; } });
    }
    return { vals: out, changed: changed };
  }
  function pictureAt(run, i) {
    for (var j = i; j >= 0; j--) {
      if (run.ticks[j].picture !== undefined) { return { src: run.pictures[run.ticks[j].picture], tick: run.ticks[j].tick }; }
    }
    return null;
  }
  function setTick(i) {
    if (!runs.length) { return; }
    var run = runs[cur.run];
    cur.tick = Math.max(0, Math.min(run.ticks.length - 1, i));
    slider.value = String(cur.tick);
    show();
  }
  function show() {
    if (!runs.length) { return; }
    var run = runs[cur.run], t = run.ticks[cur.tick];
    document.body.setAttribute("data-run", String(cur.run));
    document.body.setAttribute("data-tick", String(cur.tick));
    var info = "tick " + t.tick + " of " + (run.ticks.length - 1);
    if (t.time !== null && t.time !== undefined) { info += ", t = " + Number(t.time).toFixed(2) + " s"; }
    if (t.status) { info += ", root " + t.status; }
    if (run.loop !== null && run.loop !== undefined && cur.tick > run.loop) { info += ", in the cycle"; }
    (run.marks || []).forEach(function (m) { if (m[0] === cur.tick) { info += "; " + m[1]; } });
    $("tickinfo").textContent = info;
    document.querySelectorAll("#strip .at").forEach(function (d) { d.classList.remove("at"); });
    var cell = document.querySelector("#strip [data-t=\"" + cur.tick + "\"]");
    if (cell) { cell.classList.add("at"); }
    // the tree
    var halted = {};
    (t.halted || []).forEach(function (n) { halted[n] = true; });
    Object.keys(treeNodes).forEach(function (name) {
      var st = (t.nodes || {})[name] || "IDLE";
      treeNodes[name].forEach(function (g) {
        g.classList.remove("st-IDLE", "st-RUNNING", "st-SUCCESS", "st-FAILURE", "st-halted");
        g.classList.add("st-" + st);
        g.classList.toggle("halted", !!halted[name]);
        g.setAttribute("data-status", st);
      });
    });
    // the FSMs
    fsmPanels.forEach(function (p) {
      var at = (t.fsm || {})[p.name];
      var fired = {};
      (t.fired || []).forEach(function (x) { if (x[0] === p.name) { fired["e:" + x[1]] = true; } });
      p.views.forEach(function (v) {
        Object.keys(v.map).forEach(function (k) {
          var on = !!(at && k === "s:" + at[0]);
          v.map[k].forEach(function (g) {
            if (k.indexOf("s:") === 0) { g.classList.toggle("current", on); }
            if (k.indexOf("e:") === 0) { g.classList.toggle("fired", !!fired[k]); }
          });
        });
      });
      p.sec.setAttribute("data-state", at ? at[0] : "");
      p.sec.querySelector(".cur").textContent = at ? "at " + at[0] + (at[1] ? " (goal " + at[1] + ")" : "") : "";
    });
    // events and variables
    var lines = (t.lines || []).map(function (l) {
      var cls = l.indexOf("event ") === 0 ? "env" : l.indexOf("fired ") === 0 ? "fired" :
        (l.indexOf("violation") === 0 || l.indexOf("error") === 0) ? "bad" : "";
      return "<li class=\"" + cls + "\">" + esc(l) + "</li>";
    });
    $("events").innerHTML = lines.length ? "<ul>" + lines.join("") + "</ul>" : "<span class=\"dim\">nothing happened</span>";
    var vs = varsAt(run, cur.tick);
    function row(k) {
      return "<tr class=\"" + (vs.changed[k] ? "changed" : "") + "\"><td>" + esc(k) + "</td><td>" + esc(val(vs.vals[k])) + "</td></tr>";
    }
    var keys = Object.keys(vs.vals);
    var inner = keys.filter(function (k) { return k.indexOf(":") >= 0; });  // node memory, timers
    var open = $("vars").querySelector("details") && $("vars").querySelector("details").open;
    $("vars").innerHTML = "<table>" + keys.filter(function (k) { return k.indexOf(":") < 0; }).map(row).join("") + "</table>" +
      (inner.length ? "<details" + (open ? " open" : "") + "><summary>node memory and timers (" + inner.length + ")</summary><table>" +
        inner.map(row).join("") + "</table></details>" : "");
    var pic = pictureAt(run, cur.tick);
    $("picture").innerHTML = pic ? "<h3>the cell at tick " + pic.tick + "</h3><img alt=\"the cell\" src=\"" + pic.src + "\">" : "";
  }

  slider.addEventListener("input", function () { setTick(Number(slider.value)); });
  $("prev").addEventListener("click", function () { setTick(cur.tick - 1); });
  $("next").addEventListener("click", function () { setTick(cur.tick + 1); });
  document.addEventListener("keydown", function (ev) {
    if (ev.target && ev.target.tagName === "SELECT") { return; }
    var k = ev.key;
    if (k === "ArrowRight") { setTick(cur.tick + 1); }
    else if (k === "ArrowLeft") { setTick(cur.tick - 1); }
    else if (k === "Home") { setTick(0); }
    else if (k === "End") { setTick(1e9); }
    else if (k === "ArrowDown") { selectRun(cur.run + 1); }
    else if (k === "ArrowUp") { selectRun(cur.run - 1); }
    else { return; }
    ev.preventDefault();
  });

  // what the page shows, read back from the drawing (tests drive the page with it)
  window.btfsmView = {
    data: data,
    selectRun: selectRun,
    setTick: setTick,
    shown: function () {
      var nodes = {}, halted = [];
      Object.keys(treeNodes).forEach(function (name) {
        var g = treeNodes[name][0];
        var st = g.getAttribute("data-status");
        if (st && st !== "IDLE") { nodes[name] = st; }
        if (g.classList.contains("halted")) { halted.push(name); }
      });
      var fsm = {}, fired = [];
      fsmPanels.forEach(function (p) {
        var v = p.views[p.shown];
        var curs = v.svg.querySelectorAll("g.node.current");
        fsm[p.name] = curs.length ? curs[0].getAttribute("data-k").slice(2) : null;
        v.svg.querySelectorAll("g.fired").forEach(function (g) { fired.push([p.name, g.getAttribute("data-k").slice(2)]); });
      });
      return { run: cur.run, tick: cur.tick, slider: Number(slider.value), nodes: nodes, halted: halted.sort(), fsm: fsm, fired: fired };
    }
  };
  verdicts();
  runOptions();
  var first = 0;
  data.verdicts.some(function (v) { if (v.run !== null && v.run !== undefined) { first = v.run; return true; } return false; });
  selectRun(first);
}());
