//! The report's interactive 3-D view: the initial and final meshes (and the ground truth, when given) in a
//! WebGL canvas the reader turns with the mouse, coloured by depth, by distance to the ground truth, or by
//! support (how much of their light the data confirm, `nlos_optim::support`, for the meshes that have it).
//!
//! The page must work from the run folder alone, offline, opened as a `file://` URL: browsers refuse
//! `fetch` of local files there, so the meshes are embedded in the page (little-endian `f32` positions and
//! per-vertex scalars, `u32` corner indices, base64) and the viewer is a small inline script (WebGL 1, no
//! library). Per-vertex normals are computed in the page from the faces (area-weighted), so flat and
//! curved parts shade as they are.
//!
//! The script reports its state on `<body>`: `data-view3d="ok"` once a mesh is drawn, else
//! `data-view3d="error: …"` (for instance without WebGL), and the colouring drawn as `data-view3d-colour`
//! (`depth`, `dist` or `support`), which the headless-browser test reads.

use std::fmt::Write as _;

use nlos_mesh::SurfaceMesh;
use nlos_mesh::bvh::TriangleBvh;

use crate::Result;

/// One mesh of the view.
#[derive(Debug)]
pub struct ViewMesh<'a> {
    /// Its name in the selector ("final mesh", …).
    pub name: &'a str,
    /// The mesh.
    pub mesh: &'a SurfaceMesh,
    /// Its support per vertex of `mesh.to_triangles()`, in [−1, 1] (`nlos_optim::support`), when known.
    pub support: Option<&'a [f32]>,
}

/// Base64 (RFC 4648, with padding): a dozen lines, not worth a dependency.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], chunk.get(1).copied().unwrap_or(0), chunk.get(2).copied().unwrap_or(0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18u32, 12, 6, 0].into_iter().enumerate() {
            if i <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> shift) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn f32_base64(values: impl Iterator<Item = f32>) -> String {
    base64(&values.flat_map(f32::to_le_bytes).collect::<Vec<u8>>())
}

/// The view's HTML: a heading, the controls, the canvas and the script with the meshes embedded.
/// `ground_truth`, when given, is drawn as its own mesh and gives the "distance to the ground truth"
/// colouring (per vertex, the distance to its surface, millimetres).
///
/// # Errors
/// `ReportError::Mesh` when the ground truth's BVH cannot be built (no faces).
pub fn section(meshes: &[ViewMesh<'_>], ground_truth: Option<&SurfaceMesh>) -> Result<String> {
    let gt_bvh = ground_truth.map(TriangleBvh::from_mesh).transpose()?;
    let mut all: Vec<(&str, &SurfaceMesh, Option<&[f32]>)> =
        meshes.iter().map(|m| (m.name, m.mesh, m.support)).collect();
    if let Some(gt) = ground_truth {
        all.push(("ground truth", gt, None));
    }
    let mut js = String::from("[");
    for (name, mesh, support) in &all {
        let (positions, triangles) = mesh.to_triangles();
        if triangles.is_empty() {
            continue;
        }
        let distance: Option<Vec<f32>> =
            gt_bvh.as_ref().map(|bvh| positions.iter().map(|&p| bvh.closest_point(p).distance() * 1e3).collect());
        let support = support.filter(|s| s.len() == positions.len());
        let _ = write!(
            js,
            "{{name:{},faces:{},p:\"{}\",i:\"{}\",d:{},s:{}}},",
            serde_json::to_string(name).unwrap_or_else(|_| "\"mesh\"".into()),
            triangles.len(),
            f32_base64(positions.iter().flat_map(|p| p.to_array())),
            base64(&triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect::<Vec<u8>>()),
            distance.map_or_else(|| "null".to_string(), |d| format!("\"{}\"", f32_base64(d.into_iter()))),
            support.map_or_else(|| "null".to_string(), |s| format!("\"{}\"", f32_base64(s.iter().copied())))
        );
    }
    js.push(']');
    let mut o = String::new();
    o.push_str("<h2>3-D view</h2>\n<div class=\"view3d\">\n");
    o.push_str("<p>Drag to turn, wheel to zoom, double-click to look from the wall again. Show: ");
    for (k, (name, _, _)) in all.iter().enumerate() {
        let checked = if k + 1 == meshes.len().max(1) { " checked" } else { "" };
        let _ = write!(
            o,
            "<label><input type=\"radio\" name=\"v3mesh\" value=\"{k}\"{checked}> {}</label> ",
            crate::html::esc(name)
        );
    }
    o.push_str(" — colour: <label><input type=\"radio\" name=\"v3col\" value=\"depth\" checked> depth</label> ");
    if ground_truth.is_some() {
        o.push_str("<label><input type=\"radio\" name=\"v3col\" value=\"dist\"> distance to the ground truth</label> ");
    }
    if meshes.iter().any(|m| m.support.is_some()) {
        o.push_str(
            "<label><input type=\"radio\" name=\"v3col\" value=\"support\"> support (light the data confirm)</label>",
        );
    }
    o.push_str("</p>\n<canvas id=\"v3canvas\" width=\"900\" height=\"600\"></canvas>\n");
    o.push_str("<p id=\"v3legend\" class=\"note\"></p>\n</div>\n<script>\n\"use strict\";\nconst V3_MESHES = ");
    o.push_str(&js);
    o.push_str(";\n");
    o.push_str(SCRIPT);
    o.push_str("</script>\n");
    Ok(o)
}

/// The viewer: decode, upload, orbit camera, Lambert shading with a head light, viridis colours (the
/// polynomial fit of matplotlib's map).
const SCRIPT: &str = r#"(function () {
  const body = document.body;
  function fail(msg) { body.dataset.view3d = "error: " + msg; const l = document.getElementById("v3legend"); if (l) l.textContent = "3-D view unavailable: " + msg; }
  window.addEventListener("error", function (e) { fail(String(e.message)); });
  function bytes(b64) { const s = atob(b64); const a = new Uint8Array(s.length); for (let i = 0; i < s.length; i++) a[i] = s.charCodeAt(i); return a.buffer; }
  const canvas = document.getElementById("v3canvas");
  const gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) { fail("this browser has no WebGL"); return; }
  if (!gl.getExtension("OES_element_index_uint")) { fail("WebGL lacks 32-bit indices"); return; }
  const meshes = V3_MESHES.map(function (m) {
    const p = new Float32Array(bytes(m.p)), idx = new Uint32Array(bytes(m.i));
    const n = new Float32Array(p.length);
    for (let t = 0; t < idx.length; t += 3) {
      const a = 3 * idx[t], b = 3 * idx[t + 1], c = 3 * idx[t + 2];
      const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
      const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      for (const v of [a, b, c]) { n[v] += nx; n[v + 1] += ny; n[v + 2] += nz; }
    }
    const depth = new Float32Array(p.length / 3);
    for (let v = 0; v < depth.length; v++) depth[v] = p[3 * v + 2];
    return { name: m.name, p: p, n: n, idx: idx, depth: depth, dist: m.d ? new Float32Array(bytes(m.d)) : null, support: m.s ? new Float32Array(bytes(m.s)) : null };
  });
  if (meshes.length === 0) { fail("no mesh to show"); return; }
  // Shared bounds: every mesh in the same frame.
  let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (const m of meshes) for (let v = 0; v < m.p.length; v += 3) for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], m.p[v + k]); hi[k] = Math.max(hi[k], m.p[v + k]); }
  const centre = [0, 1, 2].map(function (k) { return (lo[k] + hi[k]) / 2; });
  const radius = Math.max(1e-6, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
  function percentile(arrays, q) { const all = []; for (const a of arrays) if (a) for (const x of a) if (isFinite(x)) all.push(x); if (!all.length) return 1; all.sort(function (x, y) { return x - y; }); return all[Math.min(all.length - 1, Math.floor(q * (all.length - 1)))]; }
  const distMax = Math.max(0.1, percentile(meshes.map(function (m) { return m.dist; }), 0.95));
  // Depth colours per mesh over its 2nd-98th percentile, so a few far fragments do not flatten the ramp.
  for (const m of meshes) { m.zlo = percentile([m.depth], 0.02); m.zhi = Math.max(m.zlo + 1e-6, percentile([m.depth], 0.98)); }
  const vs = "attribute vec3 P; attribute vec3 N; attribute float S; uniform mat4 M; uniform mat3 R; varying vec3 n; varying float s; void main() { gl_Position = M * vec4(P, 1.0); n = R * N; s = S; }";
  const fs = "precision mediump float; varying vec3 n; varying float s; " +
    "vec3 ramp(float t) { t = clamp(t, 0.0, 1.0); " +
    "const vec3 c0 = vec3(0.2777273272234177, 0.005407344544966578, 0.3340998053353061); const vec3 c1 = vec3(0.1050930431085774, 1.404613529898575, 1.384590162594685); " +
    "const vec3 c2 = vec3(-0.3308618287255563, 0.214847559468213, 0.09509516302823659); const vec3 c3 = vec3(-4.634230498983486, -5.799100973351585, -19.33244095627987); " +
    "const vec3 c4 = vec3(6.228269936347081, 14.17993336680509, 56.69055260068105); const vec3 c5 = vec3(4.776384997670288, -13.74514537774601, -65.35303263337234); " +
    "const vec3 c6 = vec3(-5.435455855934631, 4.645852612178535, 26.3124352495832); " +
    "return clamp(c0 + t * (c1 + t * (c2 + t * (c3 + t * (c4 + t * (c5 + t * c6))))), 0.0, 1.0); } " +
    "void main() { vec3 nn = normalize(n); float l = 0.25 + 0.75 * abs(nn.z); gl_FragColor = vec4(ramp(s) * l, 1.0); }";
  function shader(type, src) { const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s); if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s)); return s; }
  const prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER, vs)); gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, fs)); gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) { fail(gl.getProgramInfoLog(prog)); return; }
  gl.useProgram(prog);
  const loc = { P: gl.getAttribLocation(prog, "P"), N: gl.getAttribLocation(prog, "N"), S: gl.getAttribLocation(prog, "S"), M: gl.getUniformLocation(prog, "M"), R: gl.getUniformLocation(prog, "R") };
  function buffer(target, data) { const b = gl.createBuffer(); gl.bindBuffer(target, b); gl.bufferData(target, data, gl.STATIC_DRAW); return b; }
  for (const m of meshes) { m.bp = buffer(gl.ARRAY_BUFFER, m.p); m.bn = buffer(gl.ARRAY_BUFFER, m.n); m.bi = buffer(gl.ELEMENT_ARRAY_BUFFER, m.idx); m.bs = gl.createBuffer(); }
  // From the wall: the camera on the −z side looking along +z, y up (the wall's own frame, mirrored in x).
  let yaw = Math.PI, pitch = 0, zoom = 1;
  function choice(name) { const c = document.querySelector("input[name=" + name + "]:checked"); return c ? c.value : null; }
  function mul(a, b) { const o = new Array(16).fill(0); for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) for (let k = 0; k < 4; k++) o[i + 4 * j] += a[i + 4 * k] * b[k + 4 * j]; return o; }
  function draw() {
    const m = meshes[Math.min(meshes.length - 1, Number(choice("v3mesh") || 0))];
    const wanted = choice("v3col");
    const mode = wanted === "dist" && m.dist ? "dist" : wanted === "support" && m.support ? "support" : "depth";
    const s = new Float32Array(m.depth.length);
    for (let v = 0; v < s.length; v++) s[v] = mode === "dist" ? m.dist[v] / distMax : mode === "support" ? 0.5 * (m.support[v] + 1) : (m.depth[v] - m.zlo) / Math.max(1e-9, m.zhi - m.zlo);
    gl.bindBuffer(gl.ARRAY_BUFFER, m.bs); gl.bufferData(gl.ARRAY_BUFFER, s, gl.DYNAMIC_DRAW);
    const legend = { dist: "distance to the ground truth, 0 (dark) to " + distMax.toFixed(1) + " mm (light) and beyond",
      support: "support, -1 (dark: the capture holds none of the faces' light) to +1 (light: all of it)",
      depth: "depth, " + m.zlo.toFixed(3) + " m (dark) to " + m.zhi.toFixed(3) + " m (light)" };
    document.getElementById("v3legend").textContent = m.name + ": " + m.idx.length / 3 + " faces; colour " + legend[mode];
    body.dataset.view3dColour = mode;
    const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
    // Rotation: yaw about y, then pitch about x (column-major).
    const R = [cy, sp * sy, -cp * sy, 0, 0, cp, sp, 0, sy, -sp * cy, cp * cy, 0, 0, 0, 0, 1];
    const T = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -centre[0], -centre[1], -centre[2], 1];
    const dist = 2.4 * radius / zoom, aspect = canvas.width / canvas.height, f = 1 / Math.tan(0.35);
    const near = Math.max(1e-4, dist - 2 * radius), far = dist + 2 * radius;
    const V = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -dist, 1];
    const Pm = [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0];
    gl.uniformMatrix4fv(loc.M, false, new Float32Array(mul(Pm, mul(V, mul(R, T)))));
    gl.uniformMatrix3fv(loc.R, false, new Float32Array([R[0], R[1], R[2], R[4], R[5], R[6], R[8], R[9], R[10]]));
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(1, 1, 1, 1); gl.enable(gl.DEPTH_TEST); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    for (const [b, l, k] of [[m.bp, loc.P, 3], [m.bn, loc.N, 3], [m.bs, loc.S, 1]]) { gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.enableVertexAttribArray(l); gl.vertexAttribPointer(l, k, gl.FLOAT, false, 0, 0); }
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, m.bi);
    gl.drawElements(gl.TRIANGLES, m.idx.length, gl.UNSIGNED_INT, 0);
    body.dataset.view3d = "ok";
  }
  let drag = null;
  canvas.addEventListener("mousedown", function (e) { drag = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", function () { drag = null; });
  window.addEventListener("mousemove", function (e) { if (!drag) return; yaw += (e.clientX - drag[0]) * 0.01; pitch = Math.max(-1.5, Math.min(1.5, pitch + (e.clientY - drag[1]) * 0.01)); drag = [e.clientX, e.clientY]; draw(); });
  canvas.addEventListener("wheel", function (e) { e.preventDefault(); zoom = Math.max(0.2, Math.min(20, zoom * Math.exp(-e.deltaY * 0.001))); draw(); }, { passive: false });
  canvas.addEventListener("dblclick", function () { yaw = Math.PI; pitch = 0; zoom = 1; draw(); });
  for (const r of document.querySelectorAll("input[name=v3mesh], input[name=v3col]")) r.addEventListener("change", draw);
  draw();
})();
"#;

#[cfg(test)]
mod tests {
    use super::base64;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (input, expected) in
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("foobar", "Zm9vYmFy")]
        {
            assert_eq!(base64(input.as_bytes()), expected);
        }
    }
}
