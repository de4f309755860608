// Cylindrical impostor: the GPU twin of the CPU renderers of `altrep::cylinder`
// (src/cylinder/warp.rs `SliceView`, bounds.rs `MarchBounds::{range, march}`, offset.rs
// `OffsetTexture::{offset, sample}` and `refine`). Every per-fragment formula is the CPU's, in
// the same order of operations; conventions (columns at α_c = c·dα, x = r·sin(α − β),
// z = r·cos(α − β), sectors, march order, offsets) are those of src/cylinder/mod.rs.
//
// Per-draw tables computed by the host in f64 exactly as the CPU computes them (O(L + W + H)):
// sin/cos of α − β_c per texture column; per screen column the abscissa x and the ray's sectors
// (first, step, count; the bounds' frame); per screen row the slice (row j, weight t), the bound
// row cell, the silhouette mask interval and the y weights of the offset fetch. The fragment does
// the rest: slice interpolation, projection, facing, coverage, the march or the fetch, the
// validation and the refinement, the shading.

// Reals: per-draw scalars (see the host), then tables at the offsets stored in I.
@group(0) @binding(0) var<storage, read> R: array<real>;
// Integers: per-draw scalars, then tables at the offsets stored in I, then the bound codes.
@group(0) @binding(1) var<storage, read> I: array<i32>;
// Per texel (j·L + c): (linear albedo xyz, radius), (normal xyz, defined 1/0).
@group(0) @binding(2) var<storage, read> TEX: array<vec4<f32>>;
// Light: direction xyz, ambient.
@group(0) @binding(3) var<storage, read> LIGHT: array<f32>;
// Per fragment: sector tests of the march or of the refinement.
@group(0) @binding(4) var<storage, read_write> STEPS: array<u32>;

// Integer scalars.
const I_L: u32 = 0u;          // columns L
const I_ROWS: u32 = 1u;       // rows Ly
const I_W: u32 = 2u;          // screen width
const I_MODE: u32 = 3u;       // 0 bounded march, 1 fitted (plain), 2 hybrid
const I_M: u32 = 4u;          // hybrid: largest number of sector tests
const I_BX: u32 = 5u;         // bound cells along x
const I_RY: u32 = 6u;         // bound row cells
const I_BA: u32 = 7u;         // bound angle cell of this draw
const I_MASK: u32 = 8u;       // the offsets have a silhouette mask
const I_NX: u32 = 9u;         // offset nodes along x, y (α nodes are implied by the host's α weights)
const I_NY: u32 = 10u;
const I_AX: u32 = 11u;        // offset cells along x
const I_Z0: u32 = 12u;        // α axis: nodes z0, z1 (the host's axis_weight)
const I_Z1: u32 = 13u;
const I_OFF_TRIG: u32 = 14u;  // R offset of (sin, cos) per texture column
const I_OFF_COLX: u32 = 15u;  // R offset of x per screen column
const I_OFF_ROWR: u32 = 16u;  // R offset of (lo, hi, ty) per screen row
const I_OFF_GRID: u32 = 17u;  // R offset of the offset nodes
const I_OFF_COLI: u32 = 18u;  // I offset of (first, step, count, first_b, cell_i, base) per column
const I_OFF_ROWI: u32 = 19u;  // I offset of (j, t bits, row cell, mask ok, y0, y1) per row
const I_OFF_START: u32 = 20u; // I offset of the start codes
const I_OFF_STOP: u32 = 21u;  // I offset of the stop codes

// Real scalars.
const R_ALPHA_DA: u32 = 0u;   // α/dα
const R_TOL: u32 = 1u;        // validation tolerance, units of R
const R_KMIN: u32 = 2u;       // clamp of the fetched offset: the fitted data's range
const R_KMAX: u32 = 3u;
const R_TZ: u32 = 4u;         // α axis weight
const R_L: u32 = 5u;          // L as a real

// The current fragment's slice (set once per fragment).
var<private> ROW_J: u32;
var<private> ROW_T: f32;
var<private> ROW_LERP: bool;

fn n_cols() -> i32 {
    return I[I_L];
}

// frame.rs `sector_index`: s modulo L in [0, L).
fn sector_index(s: i32) -> u32 {
    let l = n_cols();
    return u32(((s % l) + l) % l);
}

// A texel of the slice (texture.rs `slice`: rows j and j + 1 interpolated with weight t where
// both are defined with radii of one sign).
struct Tx {
    ok: bool,
    albedo: vec3<f32>,
    normal: vec3<f32>,
    radius: f32,
};

fn texel(c: u32) -> Tx {
    let l = u32(n_cols());
    let ia = 2u * (ROW_J * l + c);
    let a = TEX[ia];
    let an = TEX[ia + 1u];
    var t: Tx;
    t.ok = an.w > 0.5;
    t.albedo = a.xyz;
    t.normal = an.xyz;
    t.radius = a.w;
    if !ROW_LERP || !t.ok {
        return t;
    }
    let ib = ia + 2u * l;
    let b = TEX[ib];
    let bn = TEX[ib + 1u];
    if !(bn.w > 0.5) || ((a.w < 0.0) != (b.w < 0.0)) {
        t.ok = false;
        return t;
    }
    // Texel::lerp: glam's lerp for the vectors, the explicit form for the radius.
    let s = ROW_T;
    t.albedo = a.xyz * (1.0 - s) + b.xyz * s;
    t.normal = an.xyz * (1.0 - s) + bn.xyz * s;
    t.radius = a.w + (b.w - a.w) * s;
    return t;
}

// SliceView `proj`: screen abscissa and depth of a defined column.
struct Proj {
    ok: bool,
    x: real,
    z: real,
    negative: bool,
};

fn project(c: u32) -> Proj {
    let t = texel(c);
    var p: Proj;
    p.ok = t.ok;
    let r = real(t.radius);
    let o = u32(I[I_OFF_TRIG]) + 2u * c;
    p.x = r * R[o];
    p.z = r * R[o + 1u];
    p.negative = t.radius < 0.0;
    return p;
}

// SliceView `edge` (+ facing and interval): columns a, a + 1, both defined, radii of one sign.
struct Edge {
    ok: bool,
    a: u32,
    b: u32,
    negative: bool,
    xa: real,
    xb: real,
    za: real,
    zb: real,
};

fn edge(a0: u32) -> Edge {
    let l = u32(n_cols());
    var e: Edge;
    e.a = a0 % l;
    e.b = (a0 + 1u) % l;
    e.ok = false;
    let pa = project(e.a);
    if !pa.ok {
        return e;
    }
    let pb = project(e.b);
    if !pb.ok || pa.negative != pb.negative {
        return e;
    }
    e.ok = true;
    e.negative = pa.negative;
    e.xa = pa.x;
    e.xb = pb.x;
    e.za = pa.z;
    e.zb = pb.z;
    return e;
}

// The visible (front-facing) edges of sector s: [outer, inner] (SliceView::new `visible`).
struct Sector {
    e: array<Edge, 2>,
};

fn front_facing(e: Edge) -> bool {
    if e.negative {
        return e.xb > e.xa;
    }
    return e.xa > e.xb;
}

fn sector(s: u32) -> Sector {
    let l = u32(n_cols());
    var out: Sector;
    var outer = edge(s);
    outer.ok = outer.ok && !outer.negative && front_facing(outer);
    var inner = edge(s + l / 2u);
    inner.ok = inner.ok && inner.negative && front_facing(inner);
    out.e[0] = outer;
    out.e[1] = inner;
    return out;
}

fn lo_of(e: Edge) -> real {
    return min(e.xa, e.xb);
}

fn hi_of(e: Edge) -> real {
    return max(e.xa, e.xb);
}

struct Frag {
    ok: bool,
    column: real,
    depth: real,
    albedo: vec3<f32>,
    normal: vec3<f32>,
};

fn no_frag() -> Frag {
    var f: Frag;
    f.ok = false;
    return f;
}

// SliceView `fragment`: the point at parameter t along edge e.
fn fragment(e: Edge, t: real) -> Frag {
    let ta = texel(e.a);
    let tb = texel(e.b);
    let s = f32(t);
    var f: Frag;
    f.ok = true;
    f.column = real(e.a) + t;
    f.depth = e.za + t * (e.zb - e.za);
    f.albedo = ta.albedo * (1.0 - s) + tb.albedo * s;
    f.normal = ta.normal * (1.0 - s) + tb.normal * s;
    return f;
}

// SliceView `point_on_edge`.
fn point_on_edge(e: Edge, x: real) -> Frag {
    let dx = e.xb - e.xa;
    var t: real = 0.0;
    if dx != 0.0 {
        t = clamp((x - e.xa) / dx, 0.0, 1.0);
    }
    return fragment(e, t);
}

// SliceView `hit_in_sector`.
fn hit_in_sector(s: u32, x: real) -> Frag {
    let sec = sector(s);
    let e0 = sec.e[0];
    let e1 = sec.e[1];
    let c0 = e0.ok && x >= lo_of(e0) && x <= hi_of(e0);
    let c1 = e1.ok && x >= lo_of(e1) && x <= hi_of(e1);
    if !c0 && !c1 {
        return no_frag();
    }
    if c0 && !c1 {
        return point_on_edge(e0, x);
    }
    if c1 && !c0 {
        return point_on_edge(e1, x);
    }
    let f0 = point_on_edge(e0, x);
    let f1 = point_on_edge(e1, x);
    if f1.depth > f0.depth {
        return f1;
    }
    return f0;
}

struct March {
    f: Frag,
    steps: u32,
};

// SliceView `march`: at most `count` sectors from `first` in direction `step`.
fn march(x: real, first: i32, step: i32, count: i32) -> March {
    var m: March;
    m.f = no_frag();
    m.steps = u32(max(count, 0));
    for (var n = 0; n < count; n++) {
        let f = hit_in_sector(sector_index(first + step * n), x);
        if f.ok {
            m.f = f;
            m.steps = u32(n + 1);
            return m;
        }
    }
    return m;
}

// MarchBounds::{range, march} with the host's per-column frame.
fn bounded(x: real, px: u32, rcell: i32) -> March {
    var m: March;
    m.f = no_frag();
    m.steps = 0u;
    let ci = I[I_OFF_COLI] + 6 * i32(px);
    let first = I[ci];
    let step = I[ci + 1];
    let count = I[ci + 2];
    let first_b = I[ci + 3];
    let cell_i = I[ci + 4];
    let base = I[ci + 5];
    let c = cell_i + I[I_BX] * (rcell + I[I_RY] * I[I_BA]);
    let sc = I[u32(I[I_OFF_STOP] + c)];
    if sc == 0 || count == 0 {
        return m;
    }
    let s_min = base + I[u32(I[I_OFF_START] + c)];
    let s_max = base + sc;
    var start: i32;
    var stop: i32;
    if step < 0 {
        start = first_b - s_max;
        stop = first_b - s_min;
    } else {
        start = s_min - first_b;
        stop = s_max - first_b;
    }
    stop = min(stop, count - 1);
    start = max(start, 0);
    if start > stop {
        return m;
    }
    return march(x, first + step * start, step, stop + 1 - start);
}

// Rust's f64::rem_euclid for |v| below a few L: whole turns added or removed one at a time
// (each exact, L an integer), then the same last addition as `v % L + L`.
fn wrap_columns(v: real) -> real {
    let l = R[R_L];
    var r = v;
    for (var i = 0; i < 64 && r >= l; i++) {
        r = r - l;
    }
    for (var i = 0; i < 64 && r < 0.0; i++) {
        r = r + l;
    }
    return r;
}

// SliceView `point_at_column` followed by the validation of `OffsetTexture::sample`.
fn plain(x: real, u: real) -> Frag {
    let l = u32(n_cols());
    let fl = floor(u);
    let a = u32(fl) % l;
    let t = u - fl;
    let e = edge(a);
    if e.ok {
        let xh = e.xa + t * (e.xb - e.xa);
        if abs(xh - x) <= R[R_TOL] {
            return fragment(e, t);
        }
        return no_frag();
    }
    var c = a;
    if !(t < 0.5) {
        c = (a + 1u) % l;
    }
    let p = project(c);
    if !p.ok || !(abs(p.x - x) <= R[R_TOL]) {
        return no_frag();
    }
    let tx = texel(c);
    var f: Frag;
    f.ok = true;
    f.column = real(c);
    f.depth = p.z;
    f.albedo = tx.albedo;
    f.normal = tx.normal;
    return f;
}

// SliceView `sectors_to`: the Newton step along the visible edge nearest x.
struct Newton {
    ok: bool,
    t: real,
};

fn sectors_to(s: u32, x: real, step: i32) -> Newton {
    var sec = sector(s);
    var best = -1;
    var best_d: real = 0.0;
    for (var k = 0; k < 2; k++) {
        let e = sec.e[k];
        if e.ok {
            let d = max(max(lo_of(e) - x, x - hi_of(e)), 0.0);
            if best < 0 || d < best_d {
                best = k;
                best_d = d;
            }
        }
    }
    var n: Newton;
    n.ok = false;
    if best < 0 {
        return n;
    }
    let e = sec.e[best];
    var front = e.xa;
    var back = e.xb;
    if step < 0 {
        front = e.xb;
        back = e.xa;
    }
    let slope = back - front;
    if slope != 0.0 {
        n.ok = true;
        n.t = (x - front) / slope;
    }
    return n;
}

// offset.rs `refine`: at most m sector tests from the sector the offset names.
fn refine(x: real, u: real, px: u32) -> March {
    var m: March;
    m.f = no_frag();
    m.steps = 0u;
    let l = n_cols();
    let ci = I[I_OFF_COLI] + 6 * i32(px);
    let first = I[ci];
    let step = I[ci + 1];
    let count = I[ci + 2];
    let mm = I[I_M];
    if count == 0 || mm == 0 {
        return m;
    }
    // SliceView::sector_of_column of ⌊u⌋.
    let c = u32(floor(u)) % u32(l);
    let tc = texel(c);
    var named = i32(c);
    if tc.ok && tc.radius < 0.0 {
        named = (i32(c) + l / 2) % l;
    }
    let along = ((((named - first) * step) % l) + l) % l;
    var n: i32;
    if along < count {
        n = along;
    } else if along - count < l - along {
        n = count - 1;
    } else {
        n = 0;
    }
    for (var it = 0; it < mm; it++) {
        let tests = u32(it + 1);
        let s = sector_index(first + step * n);
        let f = hit_in_sector(s, x);
        if f.ok {
            m.f = f;
            m.steps = tests;
            return m;
        }
        let nt = sectors_to(s, x, step);
        if !nt.ok {
            m.steps = tests;
            return m;
        }
        var jump: real;
        if nt.t >= 1.0 {
            jump = max(floor(nt.t), 1.0);
        } else {
            jump = min(floor(nt.t), -1.0);
        }
        let lr = R[R_L];
        let next = clamp(n + i32(clamp(jump, -lr, lr)), 0, count - 1);
        if next == n {
            m.steps = tests;
            return m;
        }
        n = next;
    }
    m.steps = u32(mm);
    return m;
}

fn node(i: i32, j: i32, k: i32) -> real {
    let nx = I[I_NX];
    let ny = I[I_NY];
    return R[u32(I[I_OFF_GRID] + i + nx * (j + ny * k))];
}

fn lerp_r(a: real, b: real, t: real) -> real {
    return a + t * (b - a);
}

// OffsetTexture::offset: the fetched offset k (trilinear over the nodes, TrilinearGrid::eval)
// and whether x lies in the silhouette mask; `ok` false when the mask says the slice is empty.
struct Fetch {
    ok: bool,
    k: real,
    inside: bool,
};

fn fetch(x: real, py: u32) -> Fetch {
    var f: Fetch;
    f.ok = false;
    let ri = I[I_OFF_ROWI] + 6 * i32(py);
    let rr = u32(I[I_OFF_ROWR]) + 3u * py;
    var w_x: real;
    f.inside = true;
    if I[I_MASK] != 0 {
        if I[ri + 3] == 0 {
            return f;
        }
        let lo = R[rr];
        let hi = R[rr + 1u];
        var w: real = 0.5;
        if hi > lo {
            w = (x - lo) / (hi - lo);
        }
        w_x = clamp(w, 0.0, 1.0);
        f.inside = lo <= x && x <= hi;
    } else {
        w_x = 0.5 * (x + 1.0);
    }
    // fit::axis_weight on the non-periodic x axis.
    let ax = I[I_AX];
    let sx = clamp(w_x, 0.0, 1.0) * real(ax);
    let x0 = min(i32(floor(sx)), ax - 1);
    let tx = sx - real(x0);
    let x1 = x0 + 1;
    let y0 = I[ri + 4];
    let y1 = I[ri + 5];
    let ty = R[rr + 2u];
    let z0 = I[I_Z0];
    let z1 = I[I_Z1];
    let tz = R[R_TZ];
    // TrilinearGrid::blend.
    let c00 = lerp_r(node(x0, y0, z0), node(x1, y0, z0), tx);
    let c10 = lerp_r(node(x0, y1, z0), node(x1, y1, z0), tx);
    let c01 = lerp_r(node(x0, y0, z1), node(x1, y0, z1), tx);
    let c11 = lerp_r(node(x0, y1, z1), node(x1, y1, z1), tx);
    let k = lerp_r(lerp_r(c00, c10, ty), lerp_r(c01, c11, ty), tz);
    f.ok = true;
    f.k = clamp(k, R[R_KMIN], R[R_KMAX]);
    return f;
}

// Light::shade with glam's normalize_or_zero.
fn shade(albedo: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    let light = vec4<f32>(LIGHT[0], LIGHT[1], LIGHT[2], LIGHT[3]);
    return diffuse(albedo, normalize_or_zero(normal), light);
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> FsOut {
    let px = u32(pos.x);
    let py = u32(pos.y);
    let ri = I[I_OFF_ROWI] + 6 * i32(py);
    ROW_J = u32(I[ri]);
    ROW_T = bitcast<f32>(I[ri + 1]);
    ROW_LERP = ROW_T > 0.0 && ROW_J + 1u < u32(I[I_ROWS]);
    let x = R[u32(I[I_OFF_COLX]) + px];

    var m: March;
    m.f = no_frag();
    m.steps = 0u;
    let mode = I[I_MODE];
    if mode == 0 {
        m = bounded(x, px, I[ri + 2]);
    } else {
        let f = fetch(x, py);
        if f.ok && f.inside {
            // frame.rs `offset_column`: u = (α/dα + k) mod L, in [0, L).
            var u = wrap_columns(R[R_ALPHA_DA] + f.k);
            if u >= R[R_L] {
                u = 0.0;
            }
            if mode == 1 {
                m.f = plain(x, u);
            } else {
                m = refine(x, u, px);
                if !m.f.ok {
                    m.f = plain(x, u);
                }
            }
        }
    }
    STEPS[py * u32(I[I_W]) + px] = m.steps;
    if !m.f.ok {
        discard;
    }
    // Orthographic depth: z = R (nearest) → 0, z = −R → 1.
    let depth = clamp(f32((1.0 - m.f.depth) * 0.5), 0.0, 1.0);
    return fragment_out(vec4<f32>(shade(m.f.albedo, m.f.normal), 1.0), depth);
}
