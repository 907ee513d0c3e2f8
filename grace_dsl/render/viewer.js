// GRACE-EAC scene viewer: a self-contained orbit viewer for one concept instance.
// Reads the JSON in the script element "scene-data", draws it with WebGL, or with a Canvas-2D painter's
// algorithm where WebGL is missing (or when the page's URL ends in #2d). No network, no library.
// Drag: orbit. Wheel: zoom. Shift-drag or right-drag: pan. Double-click or "r": reset.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("scene-data").textContent);
  var canvas = document.getElementById("view");

  // ---- small vector helpers -------------------------------------------------------------------
  function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
  function add(a, b) { return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]; }
  function scale(a, s) { return [a[0] * s, a[1] * s, a[2] * s]; }
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function cross(a, b) {
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  }
  function norm(a) { return Math.sqrt(dot(a, a)); }
  function unit(a) { var n = norm(a) || 1; return scale(a, 1 / n); }

  function decode(b64, Type) {
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }

  // ---- geometry: one triangle soup (flat normals) for meshes and decorations -------------------
  var tris = [];  // {p: [a, b, c], n: normal, c: [r, g, b], a: opacity, e: emission}

  data.parts.forEach(function (part, index) {
    var v = decode(part.positions, Float32Array), f = decode(part.indices, Uint32Array);
    for (var t = 0; t < f.length; t += 3) {
      var p = [0, 1, 2].map(function (k) {
        var i = 3 * f[t + k];
        return [v[i], v[i + 1], v[i + 2]];
      });
      var n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
      if (norm(n) === 0) continue;
      // p0, n0: where the part is in the scene (an animation's frame 0); p, n: where it is now
      tris.push({ p: p, n: unit(n), p0: p, n0: unit(n), part: index, c: part.color,
        a: part.opacity, e: 0 });
    }
  });

  // ---- animation: rigid motions of parts (a planned trajectory), frame by frame ---------------------
  var anim = data.animation, tracks = {};
  if (anim) {
    anim.times = decode(anim.times, Float32Array);
    anim.values = anim.values ? decode(anim.values, Float32Array) : null;
    anim.tracks.forEach(function (tr) { tracks[tr.part] = decode(tr.poses, Float32Array); });
  }

  function moveTo(frame) {  // every animated triangle to its place at `frame`
    tris.forEach(function (t) {
      var m = tracks[t.part];
      if (!m) return;
      var o = 16 * frame;
      function apply(x, w) {
        return [0, 1, 2].map(function (r) {
          var b = o + 4 * r;
          return m[b] * x[0] + m[b + 1] * x[1] + m[b + 2] * x[2] + w * m[b + 3];
        });
      }
      t.p = t.p0.map(function (x) { return apply(x, 1); });
      t.n = apply(t.n0, 0);
    });
  }

  function ring(center, u, w, r, sides) {
    var out = [];
    for (var k = 0; k < sides; k++) {
      var a = 2 * Math.PI * k / sides;
      out.push(add(center, add(scale(u, r * Math.cos(a)), scale(w, r * Math.sin(a)))));
    }
    return out;
  }

  function addTri(a, b, c, color) {
    var n = cross(sub(b, a), sub(c, a));
    if (norm(n) > 0) tris.push({ p: [a, b, c], n: unit(n), c: color, a: 1, e: 0.55 });
  }

  data.segments.forEach(function (s) {
    var d = sub(s.end, s.start), len = norm(d);
    if (len === 0) return;
    d = scale(d, 1 / len);
    var helper = Math.abs(d[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
    var u = unit(cross(d, helper)), w = cross(d, u);
    var head = s.head ? Math.min(5 * s.radius, 0.5 * len) : 0;
    var shaftEnd = add(s.start, scale(d, len - head));
    var a = ring(s.start, u, w, s.radius, 8), b = ring(shaftEnd, u, w, s.radius, 8);
    for (var k = 0; k < 8; k++) {
      var k2 = (k + 1) % 8;
      addTri(a[k], a[k2], b[k2], s.color);
      addTri(a[k], b[k2], b[k], s.color);
    }
    if (s.head) {
      var base = ring(shaftEnd, u, w, 2.4 * s.radius, 12);
      for (var j = 0; j < 12; j++) {
        addTri(base[j], base[(j + 1) % 12], s.end, s.color);
        addTri(base[(j + 1) % 12], base[j], shaftEnd, s.color);
      }
    }
  });

  // ---- camera: orbit about the target, around the scene's up direction ---------------------------
  var home = {
    target: data.view.target.slice(),
    eye: data.view.eye.slice(),
  };
  var upW = unit(data.up);
  var cam = {};

  function reset() {
    var rel = sub(home.eye, home.target);
    cam.target = home.target.slice();
    cam.dist = norm(rel);
    var h = sub(rel, scale(upW, dot(rel, upW)));
    cam.z0 = unit(h);
    cam.x0 = cross(upW, cam.z0);
    cam.az = 0;
    cam.el = Math.asin(Math.max(-1, Math.min(1, dot(rel, upW) / cam.dist)));
  }
  reset();

  function basis() {
    var ce = Math.cos(cam.el), se = Math.sin(cam.el);
    var horiz = add(scale(cam.z0, Math.cos(cam.az)), scale(cam.x0, Math.sin(cam.az)));
    var back = add(scale(horiz, ce), scale(upW, se));
    var right = unit(cross(upW, back));
    var up = cross(back, right);
    return { back: back, right: right, up: up, eye: add(cam.target, scale(back, cam.dist)) };
  }

  var L1 = unit([-0.5, 0.8, 0.6]), L2 = unit([0.8, 0.1, 0.5]);

  function shade(nView) {  // the same lighting as the WebGL shader
    var n = nView[2] < 0 ? scale(nView, -1) : nView;  // two-sided
    return 0.5 + 0.35 * Math.max(dot(n, L1), 0) + 0.15 * Math.max(dot(n, L2), 0) + 0.12 * n[2];
  }

  // ---- WebGL ---------------------------------------------------------------------------------------
  var VS = [
    "attribute vec3 aPos; attribute vec3 aNormal; attribute vec4 aColor; attribute float aEmit;",
    "uniform mat4 uMVP; uniform mat3 uRot; varying vec4 vColor;",
    "void main() {",
    "  vec3 n = normalize(uRot * aNormal); if (n.z < 0.0) n = -n;",
    "  vec3 l1 = normalize(vec3(-0.5, 0.8, 0.6)); vec3 l2 = normalize(vec3(0.8, 0.1, 0.5));",
    "  float s = 0.5 + 0.35 * max(dot(n, l1), 0.0) + 0.15 * max(dot(n, l2), 0.0) + 0.12 * n.z;",
    "  vColor = vec4(mix(aColor.rgb * s, aColor.rgb, aEmit), aColor.a);",
    "  gl_Position = uMVP * vec4(aPos, 1.0);",
    "}",
  ].join("\n");
  var FS = "precision mediump float; varying vec4 vColor;" +
    "void main() { gl_FragColor = vColor; }";

  function initGL() {
    var opts = { alpha: false, antialias: true, preserveDrawingBuffer: true };
    var gl = canvas.getContext("webgl", opts) || canvas.getContext("experimental-webgl", opts);
    if (!gl) return null;
    function shader(type, src) {
      var s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      return s;
    }
    var prog = gl.createProgram();
    gl.attachShader(prog, shader(gl.VERTEX_SHADER, VS));
    gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
    // opaque triangles first; see-through ones after, blended, without writing depth
    var order = tris.filter(function (t) { return t.a >= 1; });
    var nOpaque = order.length * 3;
    order = order.concat(tris.filter(function (t) { return t.a < 1; }));
    var n = order.length * 3;
    var pos = new Float32Array(n * 3), nor = new Float32Array(n * 3);
    var col = new Float32Array(n * 4), emi = new Float32Array(n);
    function fill() {
      order.forEach(function (t, i) {
        for (var k = 0; k < 3; k++) {
          var o = (3 * i + k) * 3;
          pos.set(t.p[k], o);
          nor.set(t.n, o);
        }
      });
    }
    fill();
    order.forEach(function (t, i) {
      for (var k = 0; k < 3; k++) {
        col.set([t.c[0], t.c[1], t.c[2], t.a], (3 * i + k) * 4);
        emi[3 * i + k] = t.e;
      }
    });
    function attrib(name, array, size) {
      var buf = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buf);
      gl.bufferData(gl.ARRAY_BUFFER, array, anim ? gl.DYNAMIC_DRAW : gl.STATIC_DRAW);
      var loc = gl.getAttribLocation(prog, name);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 0, 0);
      return buf;
    }
    gl.useProgram(prog);
    var posBuf = attrib("aPos", pos, 3);
    var norBuf = attrib("aNormal", nor, 3);
    attrib("aColor", col, 4);
    attrib("aEmit", emi, 1);
    gl.enable(gl.DEPTH_TEST);
    var uMVP = gl.getUniformLocation(prog, "uMVP"), uRot = gl.getUniformLocation(prog, "uRot");
    var drawn = function draw(m) {
      gl.viewport(0, 0, canvas.width, canvas.height);
      var bg = data.background;
      gl.clearColor(bg[0], bg[1], bg[2], 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.uniformMatrix4fv(uMVP, false, m.mvp);
      gl.uniformMatrix3fv(uRot, false, m.rot);
      gl.disable(gl.BLEND);
      gl.depthMask(true);
      gl.drawArrays(gl.TRIANGLES, 0, nOpaque);
      if (n > nOpaque) {
        gl.enable(gl.BLEND);
        gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
        gl.depthMask(false);
        gl.drawArrays(gl.TRIANGLES, nOpaque, n - nOpaque);
      }
    };
    drawn.upload = function () {  // the triangles moved (an animation frame)
      fill();
      gl.bindBuffer(gl.ARRAY_BUFFER, posBuf);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, pos);
      gl.bindBuffer(gl.ARRAY_BUFFER, norBuf);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, nor);
    };
    return drawn;
  }

  // ---- Canvas 2D: painter's algorithm, back faces of meshes culled -------------------------------------
  function init2D() {
    var ctx = canvas.getContext("2d");
    if (!ctx) return null;
    return function draw(m) {
      var W = canvas.width, H = canvas.height, b = m.basis, f = m.focal;
      var bg = data.background;
      ctx.fillStyle = rgb(bg);
      ctx.fillRect(0, 0, W, H);
      var items = [];
      tris.forEach(function (t) {
        var q = t.p.map(function (p) {
          var r = sub(p, b.eye);
          var z = -dot(r, b.back);
          return [W / 2 + f * dot(r, b.right) / z, H / 2 - f * dot(r, b.up) / z, z];
        });
        if (q[0][2] <= m.near || q[1][2] <= m.near || q[2][2] <= m.near) return;
        var area = (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[2][0] - q[0][0]) * (q[1][1] - q[0][1]);
        if (t.e === 0 && area > 0) return;  // a mesh's back face (y points down on screen)
        var nv = [dot(t.n, b.right), dot(t.n, b.up), dot(t.n, b.back)];
        var s = shade(nv), c = t.c;
        var lit = [0, 1, 2].map(function (k) { return c[k] * (s + (1 - s) * t.e); });
        var item = { q: q, depth: (q[0][2] + q[1][2] + q[2][2]) / 3, color: rgb(lit, t.a) };
        item.seal = t.a >= 1;
        items.push(item);
      });
      items.sort(function (x, y) { return y.depth - x.depth; });
      ctx.lineJoin = "round";
      ctx.lineWidth = 0.6;
      items.forEach(function (it) {
        ctx.beginPath();
        ctx.moveTo(it.q[0][0], it.q[0][1]);
        ctx.lineTo(it.q[1][0], it.q[1][1]);
        ctx.lineTo(it.q[2][0], it.q[2][1]);
        ctx.closePath();
        ctx.fillStyle = it.color;
        ctx.fill();
        if (it.seal) {  // hides the hairline seams between opaque triangles
          ctx.strokeStyle = it.color;
          ctx.stroke();
        }
      });
    };
  }

  function rgb(c, alpha) {
    var k = c.map(function (x) { return Math.round(255 * Math.max(0, Math.min(1, x))); });
    var a = alpha === undefined ? 1 : alpha;
    return "rgba(" + k[0] + "," + k[1] + "," + k[2] + "," + a + ")";
  }

  // ---- frame matrices ------------------------------------------------------------------------------
  function matrices() {
    var b = basis();
    var aspect = canvas.width / canvas.height;
    var fovy = data.view.fovy * Math.PI / 180;
    var near = Math.max(cam.dist * 0.01, 1e-4), far = cam.dist * 10 + 10 * data.size;
    var t = 1 / Math.tan(fovy / 2);
    // view: rows right, up, back; column-major storage for WebGL
    var e = b.eye;
    var view = [
      b.right[0], b.up[0], b.back[0], 0,
      b.right[1], b.up[1], b.back[1], 0,
      b.right[2], b.up[2], b.back[2], 0,
      -dot(b.right, e), -dot(b.up, e), -dot(b.back, e), 1,
    ];
    var proj = [
      t / aspect, 0, 0, 0,
      0, t, 0, 0,
      0, 0, (far + near) / (near - far), -1,
      0, 0, 2 * far * near / (near - far), 0,
    ];
    var mvp = new Float32Array(16);
    for (var c = 0; c < 4; c++) {
      for (var r = 0; r < 4; r++) {
        var s = 0;
        for (var k = 0; k < 4; k++) s += proj[k * 4 + r] * view[c * 4 + k];
        mvp[c * 4 + r] = s;
      }
    }
    var rot = new Float32Array([
      b.right[0], b.up[0], b.back[0],
      b.right[1], b.up[1], b.back[1],
      b.right[2], b.up[2], b.back[2],
    ]);
    return { mvp: mvp, rot: rot, basis: b, near: near, focal: canvas.height / 2 * t };
  }

  // ---- set up, draw, interact ----------------------------------------------------------------------
  var draw = null, mode = "2d";
  if (location.hash !== "#2d") {
    try {
      draw = initGL();
      if (draw) mode = "webgl";
    } catch (err) {
      draw = null;
    }
  }
  if (!draw) {
    // a canvas that was asked for WebGL cannot give a 2D context: use a fresh one
    var fresh = canvas.cloneNode(false);
    canvas.parentNode.replaceChild(fresh, canvas);
    canvas = fresh;
    draw = init2D();
  }
  document.body.setAttribute("data-renderer", mode);

  function resize() {
    var dpr = window.devicePixelRatio || 1;
    canvas.width = Math.max(1, Math.round(canvas.clientWidth * dpr));
    canvas.height = Math.max(1, Math.round(canvas.clientHeight * dpr));
  }

  // one draw per burst of events; a timer rather than requestAnimationFrame, which headless and
  // background pages may never run
  var pending = false;
  function redraw() {
    if (pending) return;
    pending = true;
    window.setTimeout(function () { pending = false; render(); }, 0);
  }
  function render() { if (draw) draw(matrices()); }

  var drag = null;
  canvas.addEventListener("pointerdown", function (ev) {
    drag = { x: ev.clientX, y: ev.clientY, pan: ev.shiftKey || ev.button === 2 };
    try {
      canvas.setPointerCapture(ev.pointerId);  // keep orbiting when the pointer leaves the canvas
    } catch (err) { /* synthetic or already released pointers cannot be captured */ }
  });
  canvas.addEventListener("pointermove", function (ev) {
    if (!drag) return;
    var dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
    drag.x = ev.clientX;
    drag.y = ev.clientY;
    if (drag.pan) {
      var b = basis(), k = 2 * cam.dist * Math.tan(data.view.fovy * Math.PI / 360) / canvas.clientHeight;
      cam.target = add(cam.target, add(scale(b.right, -dx * k), scale(b.up, dy * k)));
    } else {
      cam.az -= dx * 0.008;
      cam.el = Math.max(-1.55, Math.min(1.55, cam.el + dy * 0.008));
    }
    redraw();
  });
  window.addEventListener("pointerup", function () { drag = null; });
  canvas.addEventListener("contextmenu", function (ev) { ev.preventDefault(); });
  canvas.addEventListener("wheel", function (ev) {
    ev.preventDefault();
    cam.dist *= Math.exp(ev.deltaY * 0.0015);
    redraw();
  }, { passive: false });
  canvas.addEventListener("dblclick", function () { reset(); redraw(); });
  window.addEventListener("keydown", function (ev) { if (ev.key === "r") { reset(); redraw(); } });
  // resizing clears the canvas: draw again at once, not on a timer
  window.addEventListener("resize", function () { resize(); render(); });

  // ---- the player: a play button and a time slider, when the scene is animated --------------------
  var frame = 0, playing = false;
  function show(f) {
    frame = Math.max(0, Math.min(anim.frames - 1, f));
    moveTo(frame);
    if (draw.upload) draw.upload();
    document.getElementById("scrub").value = String(frame);
    var text = "t = " + anim.times[frame].toFixed(2) + " / " + anim.times[anim.frames - 1].toFixed(2) + " s";
    if (anim.values) text += ", " + anim.label + " = " + anim.values[frame].toFixed(3);
    document.getElementById("clock").textContent = text;
    document.body.setAttribute("data-frame", String(frame));
    render();
  }
  function tick() {
    if (!playing) return;
    if (frame >= anim.frames - 1) { playing = false; label(); return; }
    show(frame + 1);
    var dt = anim.times[Math.min(frame + 1, anim.frames - 1)] - anim.times[frame];
    window.setTimeout(tick, Math.max(1, 1000 * dt));
  }
  function label() { document.getElementById("play").textContent = playing ? "pause" : "play"; }
  if (anim) {
    document.getElementById("play").addEventListener("click", function () {
      playing = !playing;
      if (playing && frame >= anim.frames - 1) show(0);
      label();
      tick();
    });
    document.getElementById("scrub").addEventListener("input", function (ev) {
      playing = false;
      label();
      show(parseInt(ev.target.value, 10));
    });
  }

  resize();
  if (anim) show(0);
  render();  // at once, so the page shows the scene as soon as it is loaded
})();
