// Parallax impostor: the GPU twin of `altrep::parallax::{render, render_bounded, march}`
// (src/parallax/warp.rs). Every formula below is the CPU's, in the same order of operations; the
// conventions (θ = display angle − view angle, x_e = x_t cos θ + z_t sin θ, the march toward +x_t
// for θ ≥ 0, cells between texel centres, half-open piece test) are those of src/parallax/mod.rs.

// Scalars in `real`: see `ParallaxDisplay::render` for the layout.
@group(0) @binding(0) var<storage, read> P: array<real>;
// Integers: 0 Lx, 1 Ly, 2 k1, 3 k2, 4 bound kind (0 cylinder, 1 zmin/zmax, 2 pair, 3 best c,
// 4 best c split), 5 screen width, 6 screen height, then the reconstruction (warp.rs
// `Reconstruction`): 7 rows (0 nearest, 1 linear), 8 fallback, 9 soft edges, 10 depth test,
// 11 k0 = k1 − 1 and 12 k3 = k2 + 1 (the fallback views), 13 fill holes, 14 carve brims,
// 15 soft fallback.
@group(0) @binding(1) var<storage, read> U: array<u32>;
// Light: direction xyz (unit, object frame), ambient; then blend weights w1, w2 (f32, as the CPU),
// then the fallback views' weights w0, w3.
@group(0) @binding(2) var<storage, read> L: array<f32>;
// Per texel of every view (index (k·Ly + j)·Lx + i): linear albedo (xyz) and decoded normal (xyz).
@group(0) @binding(3) var<storage, read> ATTR: array<vec4<f32>>;
// Per texel: depth code (bits 0..15), defined (bit 16).
@group(0) @binding(4) var<storage, read> CODE: array<u32>;
// Per pixel of every view, two slots of (c, v_min, v_max, present).
@group(0) @binding(5) var<storage, read> B: array<real>;
// Per fragment: march steps of the two warped views.
@group(0) @binding(6) var<storage, read_write> STEPS: array<u32>;

const R_CAP: u32 = 0u;      // capture cylinder radius R
const PITCH: u32 = 1u;      // texel pitch δx = 2R/Lx
const MARCH_R: u32 = 2u;    // march radius R'
const THRESH: u32 = 3u;     // continuity threshold (world units)
const LEVELS: u32 = 4u;     // 2^depth_bits − 1
const CO1: u32 = 5u;
const SI1: u32 = 6u;
const CO2: u32 = 7u;
const SI2: u32 = 8u;
const SCREEN_PITCH: u32 = 9u; // 2R / screen width
const EPS: u32 = 10u;         // widening of the march ends (warp.rs: 1e-9·δx; see the host)
const CO0: u32 = 11u;         // cos, sin of θ0 = θ1 + Δθ (fallback view k0)
const SI0: u32 = 12u;
const CO3: u32 = 13u;         // cos, sin of θ3 = θ2 − Δθ (fallback view k3)
const SI3: u32 = 14u;
const MAX_SLOPE: u32 = 15u;   // brim max slope (images.rs `Brim`: 0 flat)
const VIEW_SC: u32 = 16u;     // per view k: sin α_k at 16 + 2k, cos α_k at 17 + 2k

fn x_at(u: real) -> real {
    return -P[R_CAP] + u * P[PITCH];
}

fn texel_index(k: u32, j: u32, i: u32) -> u32 {
    return (k * U[1] + j) * U[0] + i;
}

fn defined_at(idx: u32) -> bool {
    return (CODE[idx] & 0x10000u) != 0u;
}

fn depth_at(idx: u32) -> real {
    // code_value(code, bits) · 2 − 1, times R (images.rs `from_codes`).
    return (real(CODE[idx] & 0xffffu) / P[LEVELS] * 2.0 - 1.0) * P[R_CAP];
}

// Height field of one texel (images.rs `link_rows`).
struct Geom {
    defined: bool,
    z: real,
    zl: real,
    zr: real,
    link_l: bool,
    link_r: bool,
};

fn linked(a: u32, b: u32) -> bool {
    return defined_at(a) && defined_at(b) && abs(depth_at(a) - depth_at(b)) <= P[THRESH];
}

fn geom(k: u32, j: u32, i: u32) -> Geom {
    let idx = texel_index(k, j, i);
    var g: Geom;
    g.defined = defined_at(idx);
    g.z = depth_at(idx);
    g.link_l = i > 0u && linked(idx - 1u, idx);
    g.link_r = i + 1u < U[0] && linked(idx, idx + 1u);
    g.zl = g.z;
    g.zr = g.z;
    if g.link_l {
        g.zl = 0.5 * (depth_at(idx - 1u) + g.z);
    }
    if g.link_r {
        g.zr = 0.5 * (g.z + depth_at(idx + 1u));
    }
    // images.rs `apply_brim`: unjoined ends drop along the stored normal's tangent.
    if g.defined && (!g.link_l || !g.link_r) {
        let ms = P[MAX_SLOPE];
        let sa = P[VIEW_SC + 2u * k];
        let ca = P[VIEW_SC + 2u * k + 1u];
        let n = ATTR[2u * idx + 1u].xyz;
        let nx = real(n.x) * sa - real(n.z) * ca;
        let nz = real(n.x) * ca + real(n.z) * sa;
        var down_l = ms;
        var down_r = ms;
        if nz > 1e-6 {
            down_l = -nx / nz;
            down_r = nx / nz;
        }
        if !g.link_l {
            g.zl = g.z - 0.5 * P[PITCH] * clamp(down_l, 0.0, ms);
        }
        if !g.link_r {
            g.zr = g.z - 0.5 * P[PITCH] * clamp(down_r, 0.0, ms);
        }
    }
    return g;
}

struct Hit {
    ok: bool,
    texel: u32,
    right: bool,
    t: real,
    z_e: real,
};

fn no_hit() -> Hit {
    var h: Hit;
    h.ok = false;
    return h;
}

// warp.rs `try_piece` + `piece` + `hit_piece`: the ray X under θ against a half piece of texel i.
fn try_piece(k: u32, j: u32, i: u32, right: bool, x: real, co: real, si: real) -> Hit {
    let g = geom(k, j, i);
    if !g.defined {
        return no_hit();
    }
    let xc = x_at(real(i) + 0.5);
    var a = vec2<real>(x_at(real(i)), g.zl);
    var b = vec2<real>(xc, g.z);
    if right {
        a = vec2<real>(xc, g.z);
        b = vec2<real>(x_at(real(i) + 1.0), g.zr);
    }
    let ea = a.x * co + a.y * si;
    let eb = b.x * co + b.y * si;
    if ea <= x && x < eb {
        let t = (x - ea) / (eb - ea);
        let xt = a.x + t * (b.x - a.x);
        let zt = a.y + t * (b.y - a.y);
        var h: Hit;
        h.ok = true;
        h.texel = i;
        h.right = right;
        h.t = t;
        h.z_e = zt * co - xt * si;
        return h;
    }
    return no_hit();
}

// warp.rs `cell`: cell index c ∈ [−1, Lx − 1] of abscissa x.
fn cell(x: real) -> i32 {
    let u = (x + P[R_CAP]) / P[PITCH] - 0.5;
    return i32(min(max(floor(u), -1.0), real(i32(U[0]) - 1)));
}

struct March {
    hit: Hit,
    steps: u32,
};

// warp.rs `march_row`.
fn march_row(k: u32, j: u32, x: real, co: real, si: real, x1: real, x2: real) -> March {
    let w = i32(U[0]);
    let eps = P[EPS];
    var m: March;
    m.hit = no_hit();
    m.steps = 0u;
    if si >= 0.0 {
        if x1 > x2 {
            return m;
        }
        let c1 = cell(x1 - eps);
        let c2 = cell(x2 + eps);
        for (var c = c1; c <= c2; c++) {
            m.steps += 1u;
            if c >= 0 {
                let h = try_piece(k, j, u32(c), true, x, co, si);
                if h.ok {
                    m.hit = h;
                    return m;
                }
            }
            if c + 1 < w {
                let h = try_piece(k, j, u32(c + 1), false, x, co, si);
                if h.ok {
                    m.hit = h;
                    return m;
                }
            }
        }
    } else {
        if x1 < x2 {
            return m;
        }
        let c1 = cell(x1 + eps);
        let c2 = cell(x2 - eps);
        for (var c = c1; c >= c2; c--) {
            m.steps += 1u;
            if c + 1 < w {
                let h = try_piece(k, j, u32(c + 1), false, x, co, si);
                if h.ok {
                    m.hit = h;
                    return m;
                }
            }
            if c >= 0 {
                let h = try_piece(k, j, u32(c), true, x, co, si);
                if h.ok {
                    m.hit = h;
                    return m;
                }
            }
        }
    }
    return m;
}

// A march range (x1, x2) and whether it is empty.
struct Range {
    ok: bool,
    x1: real,
    x2: real,
};

fn range_of(ok: bool, x1: real, x2: real) -> Range {
    var r: Range;
    r.ok = ok;
    r.x1 = x1;
    r.x2 = x2;
    return r;
}

// warp.rs `cylinder_range`.
fn cylinder_range(x: real, co: real, si: real) -> Range {
    let r = P[MARCH_R];
    let h = sqrt(max(r * r - x * x, 0.0));
    return range_of(true, x * co - h * si, x * co + h * si);
}

// bounds.rs `clip`.
fn clip(a: Range, cyl: Range, forward: bool) -> Range {
    if !a.ok {
        return a;
    }
    if forward {
        let lo = max(a.x1, cyl.x1);
        let hi = min(a.x2, cyl.x2);
        return range_of(lo <= hi, lo, hi);
    }
    let lo = min(a.x1, cyl.x1);
    let hi = max(a.x2, cyl.x2);
    return range_of(lo >= hi, lo, hi);
}

// `PixelBound::range` of slot s of pixel idx (present flag in the fourth value).
fn slot_range(idx: u32, s: u32, x: real, co: real, si: real) -> Range {
    let o = idx * 8u + s * 4u;
    let c = B[o];
    let base = (1.0 + c * (1.0 - co)) * x;
    return range_of(B[o + 3u] > 0.5, base - B[o + 2u] * si, base - B[o + 1u] * si);
}

// bounds.rs `Bounds::range_cs` for the selected kind.
fn march_range(k: u32, idx: u32, x: real, co: real, si: real) -> Range {
    let cyl = cylinder_range(x, co, si);
    let fw = si >= 0.0;
    let kind = U[4];
    let pix = k * U[0] * U[1] + idx;
    if kind == 0u {
        return clip(cyl, cyl, fw);
    }
    if kind == 1u || kind == 3u {
        return clip(slot_range(pix, 0u, x, co, si), cyl, fw);
    }
    if kind == 4u {
        return clip(slot_range(pix, select(0u, 1u, fw), x, co, si), cyl, fw);
    }
    // The pair: the shorter clipped interval.
    let a = clip(slot_range(pix, 0u, x, co, si), cyl, fw);
    let b = clip(slot_range(pix, 1u, x, co, si), cyl, fw);
    if a.ok && b.ok {
        if abs(a.x2 - a.x1) <= abs(b.x2 - b.x1) {
            return a;
        }
        return b;
    }
    if a.ok {
        return a;
    }
    return b;
}

// warp.rs `crossing_attributes` + `shade_crossing`.
fn shade(k: u32, j: u32, h: Hit) -> vec3<f32> {
    let idx = texel_index(k, j, h.texel);
    let g = geom(k, j, h.texel);
    let t = f32(h.t);
    var a = ATTR[2u * idx].xyz;
    var n = ATTR[2u * idx + 1u].xyz;
    if h.right {
        if g.link_r {
            let s = 0.5 * t;
            a = a + s * (ATTR[2u * idx + 2u].xyz - a);
            n = n + s * (ATTR[2u * idx + 3u].xyz - n);
        }
    } else if g.link_l {
        let ma = 0.5 * (ATTR[2u * idx - 2u].xyz + a);
        let mn = 0.5 * (ATTR[2u * idx - 1u].xyz + n);
        a = ma + t * (a - ma);
        n = mn + t * (n - mn);
    }
    return diffuse(a, normalize_or_zero(n), vec4<f32>(L[0], L[1], L[2], L[3]));
}

// warp.rs `edge_coverage`: 1 − u/2 on a brim (u from the texel centre outward), else 1.
fn edge_coverage(k: u32, j: u32, h: Hit) -> f32 {
    let g = geom(k, j, h.texel);
    if h.right && !g.link_r {
        return f32(1.0 - 0.5 * h.t);
    }
    if !h.right && !g.link_l {
        return f32(1.0 - 0.5 * (1.0 - h.t));
    }
    return 1.0;
}

// warp.rs `on_brim`.
fn on_brim(k: u32, j: u32, h: Hit) -> bool {
    let g = geom(k, j, h.texel);
    if h.right {
        return !g.link_r;
    }
    return !g.link_l;
}

// A combined ray: premultiplied colour, depth of the nearer crossing, whether anything hit.
struct Col {
    ok: bool,
    c: vec4<f32>,
    z_e: real,
};

fn soft(k: u32, j: u32, h: Hit) -> vec4<f32> {
    let col = shade(k, j, h);
    if U[9] != 0u {
        let cov = edge_coverage(k, j, h);
        return vec4<f32>(col * cov, cov);
    }
    return vec4<f32>(col, 1.0);
}

// warp.rs `project`: the screen point (x, z_e) in the frame of a view seen under (co, si): its
// texel coordinate u and its depth z_t.
fn project(co: real, si: real, x: real, z_e: real) -> vec2<real> {
    let xt = x * co - z_e * si;
    let zt = x * si + z_e * co;
    return vec2<real>((xt + P[R_CAP]) / P[PITCH], zt);
}

// warp.rs `CARVE_DEPTH_TEXELS`.
const CARVE_DEPTH_TEXELS: f32 = 2.0;

// warp.rs `DOUBTFUL_FALLBACK_COVERAGE`.
const DOUBTFUL_FALLBACK_COVERAGE: f32 = 0.5;

// warp.rs `sticks_out`: whether the hit `a` of view ka on the ray x of row j, which view kb
// (seen under (co, si)) misses, is a brim sticking out past kb's outline.
fn sticks_out(ka: u32, kb: u32, co: real, si: real, j: u32, x: real, a: Hit) -> bool {
    if !on_brim(ka, j, a) {
        return false;
    }
    let pr = project(co, si, x, a.z_e);
    let u = pr.x;
    let zt = pr.y;
    let w = real(U[0]);
    let i = floor(u);
    if i >= 0.0 && i < w && geom(kb, j, u32(i)).defined {
        return false;
    }
    let window = real(CARVE_DEPTH_TEXELS) * P[PITCH];
    for (var d = -1; d <= 1; d += 2) {
        let n = i + real(d);
        if n >= 0.0 && n < w {
            let g = geom(kb, j, u32(n));
            if g.defined && abs(g.z - zt) <= window {
                return true;
            }
        }
    }
    return false;
}

// warp.rs `combine`: the crossings a (view ka, weight wa) and b (view kb, weight wb) of the ray
// x; (coa, sia) and (cob, sib) are the cosines and sines of the angles the views are seen under.
fn combine(ka: u32, kb: u32, wa: f32, wb: f32, j: u32, a: Hit, b: Hit, x: real, coa: real, sia: real, cob: real, sib: real) -> Col {
    var o: Col;
    o.ok = a.ok || b.ok;
    o.c = vec4<f32>(0.0);
    o.z_e = 0.0;
    if U[14] != 0u && a.ok != b.ok {
        var cut = false;
        if a.ok {
            cut = sticks_out(ka, kb, cob, sib, j, x, a);
        } else {
            cut = sticks_out(kb, ka, coa, sia, j, x, b);
        }
        if cut {
            o.ok = false;
            return o;
        }
    }
    if a.ok && b.ok {
        o.z_e = max(a.z_e, b.z_e);
        if U[10] != 0u && abs(a.z_e - b.z_e) > P[THRESH] {
            if a.z_e > b.z_e {
                o.c = soft(ka, j, a);
                o.z_e = a.z_e;
            } else {
                o.c = soft(kb, j, b);
                o.z_e = b.z_e;
            }
        } else if U[9] != 0u && on_brim(ka, j, a) && on_brim(kb, j, b) {
            o.c = wa * soft(ka, j, a) + wb * soft(kb, j, b);
        } else {
            o.c = vec4<f32>(wa * shade(ka, j, a) + wb * shade(kb, j, b), 1.0);
        }
    } else if a.ok {
        o.c = soft(ka, j, a);
        o.z_e = a.z_e;
    } else if b.ok {
        o.c = soft(kb, j, b);
        o.z_e = b.z_e;
    }
    return o;
}

// warp.rs `hidden_in`: whether the screen point (x, z_e) lies below the surface of a defined
// texel of row j of view k seen under (co, si).
fn hidden_in(k: u32, co: real, si: real, j: u32, x: real, z_e: real) -> bool {
    let pr = project(co, si, x, z_e);
    let u = pr.x;
    let zt = pr.y;
    if !(u >= 0.0 && u < real(U[0])) {
        return false;
    }
    let i = u32(floor(u));
    let g = geom(k, j, i);
    if !g.defined {
        return false;
    }
    let f = u - real(i);
    var h = g.z + (g.zr - g.z) * (2.0 * f - 1.0);
    if f < 0.5 {
        h = g.zl + (g.z - g.zl) * 2.0 * f;
    }
    return zt < h;
}

// A wall crossing for hole filling: the texel on the far side of the step and the depth.
struct Wall {
    ok: bool,
    hit: Hit,
};

// warp.rs `first_wall`, one boundary: the step between texels i and i + 1 of view k.
fn wall_at(k: u32, j: u32, i: u32, x: real, co: real, si: real, ko: u32, cko: real, sko: real) -> Wall {
    var w: Wall;
    w.ok = false;
    let a = geom(k, j, i);
    let b = geom(k, j, i + 1u);
    if !(a.defined && b.defined) || a.link_r {
        return w;
    }
    let xb = x_at(real(i) + 1.0);
    let z = (x - xb * co) / si;
    var lo = b.zl;
    var hi = a.zr;
    var lower = i + 1u;
    var right = false;
    if si > 0.0 {
        lo = a.zr;
        hi = b.zl;
        lower = i;
        right = true;
    }
    let z_e = z * co - xb * si;
    if lo <= z && z < hi && hidden_in(ko, cko, sko, j, x, z_e) {
        w.ok = true;
        w.hit.ok = true;
        w.hit.texel = lower;
        w.hit.right = right;
        w.hit.t = 0.0;
        if right {
            w.hit.t = 1.0;
        }
        w.hit.z_e = z_e;
    }
    return w;
}

// warp.rs `first_wall` from the cylinder, accepting walls that view ko also hides.
fn first_wall(k: u32, j: u32, x: real, co: real, si: real, ko: u32, cko: real, sko: real) -> Wall {
    var w: Wall;
    w.ok = false;
    if si == 0.0 {
        return w;
    }
    let q = cylinder_range(x, co, si);
    let c1 = cell(q.x1);
    let c2 = cell(q.x2);
    let last = i32(U[0]) - 2;
    if si > 0.0 {
        for (var c = max(c1, 0); c <= min(c2, last); c++) {
            w = wall_at(k, j, u32(c), x, co, si, ko, cko, sko);
            if w.ok {
                return w;
            }
        }
    } else {
        for (var c = min(c1, last); c >= max(c2, 0); c--) {
            w = wall_at(k, j, u32(c), x, co, si, ko, cko, sko);
            if w.ok {
                return w;
            }
        }
    }
    return w;
}

// warp.rs `hole_fill`: the nearer accepted wall of the two bracketing views, opaque.
fn hole_fill(j: u32, x: real) -> Col {
    let k1 = U[2];
    let k2 = U[3];
    let a = first_wall(k1, j, x, P[CO1], P[SI1], k2, P[CO2], P[SI2]);
    let b = first_wall(k2, j, x, P[CO2], P[SI2], k1, P[CO1], P[SI1]);
    var o: Col;
    o.ok = a.ok || b.ok;
    o.c = vec4<f32>(0.0);
    o.z_e = 0.0;
    if a.ok && (!b.ok || !(b.hit.z_e > a.hit.z_e)) {
        o.c = vec4<f32>(shade(k1, j, a.hit), 1.0);
        o.z_e = a.hit.z_e;
    } else if b.ok {
        o.c = vec4<f32>(shade(k2, j, b.hit), 1.0);
        o.z_e = b.hit.z_e;
    }
    return o;
}

// One ray on view row j: the bracketing views within the march range of the pixel's bounds,
// then, where both miss, the fallback views from the cylinder (warp.rs `render_bounded_with`,
// `render_with`). Steps of the bracketing views only.
struct RowOut {
    col: Col,
    s1: u32,
    s2: u32,
};

fn ray_row(j: u32, x: real, px: u32) -> RowOut {
    // Stored bounds are per texel: the host only selects them at the views' own size.
    let idx = j * U[0] + min(px, U[0] - 1u);
    let k1 = U[2];
    let k2 = U[3];
    var m1: March;
    m1.hit = no_hit();
    m1.steps = 0u;
    var m2 = m1;
    let r1 = march_range(k1, idx, x, P[CO1], P[SI1]);
    if r1.ok {
        m1 = march_row(k1, j, x, P[CO1], P[SI1], r1.x1, r1.x2);
    }
    let r2 = march_range(k2, idx, x, P[CO2], P[SI2]);
    if r2.ok {
        m2 = march_row(k2, j, x, P[CO2], P[SI2], r2.x1, r2.x2);
    }
    var o: RowOut;
    o.s1 = m1.steps;
    o.s2 = m2.steps;
    o.col = combine(k1, k2, L[4], L[5], j, m1.hit, m2.hit, x, P[CO1], P[SI1], P[CO2], P[SI2]);
    if !o.col.ok && U[8] != 0u {
        let k0 = U[11];
        let k3 = U[12];
        let q0 = cylinder_range(x, P[CO0], P[SI0]);
        let m0 = march_row(k0, j, x, P[CO0], P[SI0], q0.x1, q0.x2);
        let q3 = cylinder_range(x, P[CO3], P[SI3]);
        let m3 = march_row(k3, j, x, P[CO3], P[SI3], q3.x1, q3.x2);
        o.col = combine(k0, k3, L[6], L[7], j, m0.hit, m3.hit, x, P[CO0], P[SI0], P[CO3], P[SI3]);
        // warp.rs `fallback_coverage`: one fallback view alone hits, on a brim sticking out
        // past a bracketing view's outline.
        if o.col.ok && U[15] != 0u && m0.hit.ok != m3.hit.ok {
            var ka = k0;
            var h = m0.hit;
            if m3.hit.ok {
                ka = k3;
                h = m3.hit;
            }
            if sticks_out(ka, k1, P[CO1], P[SI1], j, x, h) || sticks_out(ka, k2, P[CO2], P[SI2], j, x, h) {
                o.col.c = o.col.c * DOUBTFUL_FALLBACK_COVERAGE;
            }
        }
    }
    if !o.col.ok && U[13] != 0u {
        o.col = hole_fill(j, x);
    }
    return o;
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> FsOut {
    let px = u32(pos.x);
    let py = u32(pos.y);
    let sw = U[5];
    let sh = U[6];
    let ly = U[1];
    // RenderParams::sample_xs (one ray per pixel).
    let x = -P[R_CAP] + (real(px) + 0.5) * P[SCREEN_PITCH];
    var acc = vec4<f32>(0.0);
    var hit = false;
    var z_e = -P[MARCH_R];
    var s1 = 0u;
    var s2 = 0u;
    // The view rows read: RenderParams::view_row, the nearest row (weight 1), or
    // RenderParams::row_weights (one sub-row), rows j0 and j0 + 1 linearly. One call site of
    // `ray_row` for both: the shader compiler inlines every call, and a second copy of the
    // whole march doubles the compile time on software adapters.
    let linear = U[7] != 0u;
    var j0 = 0;
    var f = real(0.0);
    var rows = 1;
    if linear {
        let v = (real(py) + 0.5) * (real(ly) / real(sh)) - 0.5;
        let fl = floor(v);
        j0 = i32(fl);
        f = v - fl;
        rows = 2;
    } else {
        j0 = i32(min(u32(floor((real(py) + 0.5) * real(ly) / real(sh))), ly - 1u));
    }
    for (var q = 0; q < rows; q++) {
        let j = j0 + q;
        var w = 1.0 - f;
        if q == 1 {
            w = f;
        }
        if linear && (j < 0 || j >= i32(ly) || w <= 0.0) {
            continue;
        }
        let o = ray_row(u32(j), x, px);
        s1 += o.s1;
        s2 += o.s2;
        if o.col.ok {
            hit = true;
            if linear {
                acc += o.col.c * f32(w);
                z_e = max(z_e, o.col.z_e);
            } else {
                acc = o.col.c;
                z_e = o.col.z_e;
            }
        }
    }
    let frag = 2u * (py * sw + px);
    STEPS[frag] = s1;
    STEPS[frag + 1u] = s2;
    if !hit {
        discard;
    }
    // Orthographic depth: z_e = R' (nearest) → 0, z_e = −R' → 1.
    let r = P[MARCH_R];
    return fragment_out(acc, clamp(f32((r - z_e) / (2.0 * r)), 0.0, 1.0));
}
