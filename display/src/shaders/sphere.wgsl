// Images with parallax from any direction: the GPU twin of `altrep::sphere::render` at one ray per
// pixel (src/sphere/warp.rs). Every formula below is the CPU's, in the same order of operations;
// the conventions (frame units over the bounding sphere, texel coordinates, the surface of a texel,
// free points, carving free space) are those of src/sphere/mod.rs.

// Scalars in `real`, see `SphereDisplay::render`: 0 F (texels per frame side), 1 visibility
// (texel pitches), 2 "infinity", 3 the CPU's 1e-300 (smallest direction component marched),
// 4 screen size, 5 the tolerance of `hidden` (the CPU's 1e-9; see the host), 6 how far past a
// candidate it is checked and coloured (warp.rs `PROBE`), 7 the hole depth ("infinity": none);
// then per frame slot s at 8 + 10·s (the enclosing frames first, then the extra frames, the
// nearest to the direction first): rows X, Y, Z of its map (9 values, row-major) and its weight.
@group(0) @binding(0) var<storage, read> P: array<real>;
// Integers: 0 number of enclosing frames (1..3), 1 number of extra frames (0..MAX_EXTRA_FRAMES),
// 2 use the bounds, 3 the cap on a ray's fetches (warp.rs `SphereRenderParams::max_steps`; the
// largest u32: none), 4 how a hole is drawn (1: from the one-step offsets, warp.rs
// `HoleFill::Offsets`; 0: from the nearest frame surface), then 5 + s the frame index of slot s.
@group(0) @binding(1) var<storage, read> U: array<u32>;
// Light: direction xyz (unit, object frame), ambient.
@group(0) @binding(2) var<storage, read> L: array<f32>;
// Per texel of every frame (index (k·F + j)·F + i): stored depth Z, slope ∂Z/∂X, ∂Z/∂Y.
@group(0) @binding(3) var<storage, read> TEX: array<real>;
// Per texel: linear albedo (xyz), then unit normal (xyz), two vec4 each.
@group(0) @binding(4) var<storage, read> ATTR: array<vec4<f32>>;
// Per texel: bit 0 defined, bit 1 an event is possible (zmin ≤ zmax), bits 8..15 zmin code,
// bits 16..23 zmax code (8-bit codes of [−1, 1]).
@group(0) @binding(5) var<storage, read> CODE: array<u32>;
// Per fragment: texel fetches of the ray; flags (bit 0 no frame sees the point, bit 1 still
// unresolved after the carving rounds, bit 2 the ray was traced: inside the sphere's disc, bit 3
// stopped by the cap on fetches).
@group(0) @binding(6) var<storage, read_write> STEPS: array<u32>;

const MAX_CARVE_ROUNDS: u32 = 8u;
// warp.rs `MAX_EXTRA_FRAMES`; the frame slots hold 3 enclosing frames and these.
const MAX_SLOTS: u32 = 11u;

var<private> steps: u32;

fn size_f() -> real {
    return P[0];
}

fn size_u() -> u32 {
    return u32(P[0]);
}

// frames.rs `Frame::pitch`.
fn pitch() -> real {
    return real(2.0) / P[0];
}

// frames.rs `Frame::texel_coords`.
fn texel_coords(p: vec2<real>) -> vec2<real> {
    return vec2<real>((p.x + real(1.0)) / pitch(), (real(1.0) - p.y) / pitch());
}

// frames.rs `Frame::cell`: the texel index if (i, j) is inside frame k and defined, else −1.
fn cell(k: u32, i: i32, j: i32) -> i32 {
    let f = i32(size_u());
    if i < 0 || j < 0 || i >= f || j >= f {
        return -1;
    }
    let idx = (k * size_u() + u32(j)) * size_u() + u32(i);
    if (CODE[idx] & 1u) == 0u {
        return -1;
    }
    return i32(idx);
}

// frames.rs `Frame::height`: the plane of texel `idx` at frame position p.
fn height(idx: u32, p: vec2<real>) -> real {
    let f = size_u();
    let local = idx % (f * f);
    let i = local % f;
    let j = local / f;
    let c = vec2<real>(
        real(-1.0) + (real(i) + real(0.5)) * pitch(),
        real(1.0) - (real(j) + real(0.5)) * pitch(),
    );
    let d = p - c;
    return TEX[3u * idx] + (TEX[3u * idx + 1u] * d.x + TEX[3u * idx + 2u] * d.y);
}

// The cell containing p (frames.rs `height_at`), −1 where undefined or outside.
fn cell_at(k: u32, p: vec2<real>) -> i32 {
    let t = texel_coords(p);
    return cell(k, i32(floor(t.x)), i32(floor(t.y)));
}

// warp.rs `hidden`: the frame point (p, z) is not free.
fn hidden(k: u32, p: vec2<real>, z: real) -> bool {
    let c = cell_at(k, p);
    return c >= 0 && height(u32(c), p) >= z - P[5];
}

struct Event {
    found: bool,
    z: real,
};

// warp.rs `first_event`: marches P(Z) = q + Z·t through frame k from Z = z_hi down to z_lo, one
// fetch per cell, and returns the frame depth of the first point that is not free; once the
// ray's fetches reach the cap (U[3]), the depth of the point reached.
fn first_event(k: u32, q: vec2<real>, t: vec2<real>, z_hi: real, z_lo: real) -> Event {
    var none: Event;
    none.found = false;
    none.z = real(0.0);
    if z_hi < z_lo {
        return none;
    }
    let pit = pitch();
    let f = size_f();
    let tiny = P[3];
    let inf = P[2];
    let start = texel_coords(q + z_hi * t);
    let du = -t.x / pit;
    let dv = t.y / pit;
    let len = z_hi - z_lo;
    var l0 = real(0.0);
    var l1 = len;
    // Clip to the frame square [0, F]²: outside it everything is free.
    if abs(du) < tiny {
        if !(start.x >= real(0.0) && start.x <= f) {
            return none;
        }
    } else {
        let a = (real(0.0) - start.x) / du;
        let b = (f - start.x) / du;
        l0 = max(l0, min(a, b));
        l1 = min(l1, max(a, b));
    }
    if abs(dv) < tiny {
        if !(start.y >= real(0.0) && start.y <= f) {
            return none;
        }
    } else {
        let a = (real(0.0) - start.y) / dv;
        let b = (f - start.y) / dv;
        l0 = max(l0, min(a, b));
        l1 = min(l1, max(a, b));
    }
    if l0 > l1 {
        return none;
    }
    let p_in = vec2<real>(start.x + du * l0, start.y + dv * l0);
    let fs = i32(size_u());
    var i = clamp(i32(floor(p_in.x)), 0, fs - 1);
    var j = clamp(i32(floor(p_in.y)), 0, fs - 1);
    var si = -1;
    if du > real(0.0) {
        si = 1;
    }
    var sj = -1;
    if dv > real(0.0) {
        sj = 1;
    }
    var tmax_x = inf;
    if !(abs(du) < tiny) {
        var edge = i;
        if si > 0 {
            edge = i + 1;
        }
        tmax_x = l0 + max((real(edge) - p_in.x) / du, real(0.0));
    }
    var tmax_y = inf;
    if !(abs(dv) < tiny) {
        var edge = j;
        if sj > 0 {
            edge = j + 1;
        }
        tmax_y = l0 + max((real(edge) - p_in.y) / dv, real(0.0));
    }
    var dx = inf;
    if !(abs(du) < tiny) {
        dx = real(1.0) / abs(du);
    }
    var dy = inf;
    if !(abs(dv) < tiny) {
        dy = real(1.0) / abs(dv);
    }
    var l_in = l0;
    // A line crosses at most 2F cells of the square; the bound only guards the loop.
    for (var n = 0; n < 4 * fs + 8; n = n + 1) {
        if steps >= U[3] {
            var e: Event;
            e.found = true;
            e.z = z_hi - l_in;
            return e;
        }
        let l_out = min(min(tmax_x, tmax_y), l1);
        steps = steps + 1u;
        let c = cell(k, i, j);
        if c >= 0 {
            let pa = vec2<real>(start.x + du * l_in, start.y + dv * l_in);
            let pb = vec2<real>(start.x + du * l_out, start.y + dv * l_out);
            let p_a = vec2<real>(pa.x * pit - real(1.0), real(1.0) - pa.y * pit);
            let p_b = vec2<real>(pb.x * pit - real(1.0), real(1.0) - pb.y * pit);
            let f_in = height(u32(c), p_a) - (z_hi - l_in);
            let f_out = height(u32(c), p_b) - (z_hi - l_out);
            if f_in >= real(0.0) {
                var e: Event;
                e.found = true;
                e.z = z_hi - l_in;
                return e;
            }
            if f_out >= real(0.0) {
                var e: Event;
                e.found = true;
                e.z = z_hi - (l_in + (l_out - l_in) * (-f_in) / (f_out - f_in));
                return e;
            }
        }
        if l_out >= l1 {
            return none;
        }
        if tmax_x <= tmax_y {
            i = i + si;
            tmax_x = tmax_x + dx;
        } else {
            j = j + sj;
            tmax_y = tmax_y + dy;
        }
        if i < 0 || j < 0 || i >= fs || j >= fs {
            return none;
        }
        l_in = l_out;
    }
    return none;
}

// The line of display ray (x, y) in the frame of slot s (warp.rs `FrameMap::line`).
struct Line {
    k: u32,
    a: real,
    c: real,
    q: vec2<real>,
    t: vec2<real>,
    lo: real,
    hi: real,
};

fn map_at(s: u32, r: u32, col: u32) -> real {
    return P[8u + 10u * s + 3u * r + col];
}

fn line_of(s: u32, x: real, y: real) -> Line {
    var l: Line;
    l.k = U[5u + s];
    l.c = map_at(s, 2u, 2u);
    l.a = map_at(s, 2u, 0u) * x + map_at(s, 2u, 1u) * y;
    let z0 = -l.a / l.c;
    l.q = vec2<real>(
        map_at(s, 0u, 0u) * x + map_at(s, 0u, 1u) * y + map_at(s, 0u, 2u) * z0,
        map_at(s, 1u, 0u) * x + map_at(s, 1u, 1u) * y + map_at(s, 1u, 2u) * z0,
    );
    l.t = vec2<real>(map_at(s, 0u, 2u) / l.c, map_at(s, 1u, 2u) / l.c);
    return l;
}

// The frame point and depth of display depth z on a line (warp.rs `trace`, `at`).
fn at_p(l: Line, z: real) -> vec2<real> {
    let zf = l.a + l.c * z;
    return l.q + zf * l.t;
}

fn at_z(l: Line, z: real) -> real {
    return l.a + l.c * z;
}

fn code_value(c: u32) -> real {
    return real(c) / real(255.0) * real(2.0) - real(1.0);
}

// The light (data-gen `Light::shade`).
fn shade(albedo: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    return diffuse(albedo, normal, vec4<f32>(L[0], L[1], L[2], L[3]));
}

struct Attr {
    found: bool,
    albedo: vec3<f32>,
    normal: vec3<f32>,
};

// frames.rs `Frame::attributes_at`: bilinear over the defined texels among the four nearest
// centres (renormalised weights), else the texel containing p.
fn attributes_at(k: u32, p: vec2<real>) -> Attr {
    var out: Attr;
    out.found = false;
    let t = texel_coords(p) - vec2<real>(real(0.5), real(0.5));
    let i0 = i32(floor(t.x));
    let j0 = i32(floor(t.y));
    let fx = f32(t.x - real(i0));
    let fy = f32(t.y - real(j0));
    var a = vec3<f32>(0.0);
    var n = vec3<f32>(0.0);
    var w = 0.0;
    let di = array<i32, 4>(0, 1, 0, 1);
    let dj = array<i32, 4>(0, 0, 1, 1);
    let wt = array<f32, 4>((1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy);
    for (var m = 0; m < 4; m = m + 1) {
        let c = cell(k, i0 + di[m], j0 + dj[m]);
        if c >= 0 && wt[m] > 0.0 {
            a = a + ATTR[2u * u32(c)].xyz * wt[m];
            n = n + ATTR[2u * u32(c) + 1u].xyz * wt[m];
            w = w + wt[m];
        }
    }
    if w <= 0.0 {
        let c = cell_at(k, p);
        if c < 0 {
            return out;
        }
        out.found = true;
        out.albedo = ATTR[2u * u32(c)].xyz;
        out.normal = ATTR[2u * u32(c) + 1u].xyz;
        return out;
    }
    out.found = true;
    out.albedo = a / w;
    let nn = n / w;
    let len = sqrt(dot(nn, nn));
    out.normal = vec3<f32>(0.0);
    if len > 0.0 {
        out.normal = nn * (1.0 / len);
    }
    return out;
}

// frames.rs `Frame::bilinear` of the stored depth: (Σ w·Z, Σ w) over the defined texels among
// the four nearest centres to p, w their bilinear weights (Σ w is the bilinear coverage).
fn bilinear_depth(k: u32, p: vec2<real>) -> vec2<real> {
    let t = texel_coords(p) - vec2<real>(real(0.5), real(0.5));
    let i0 = i32(floor(t.x));
    let j0 = i32(floor(t.y));
    let fx = t.x - real(i0);
    let fy = t.y - real(j0);
    let di = array<i32, 4>(0, 1, 0, 1);
    let dj = array<i32, 4>(0, 0, 1, 1);
    let wt = array<real, 4>(
        (real(1.0) - fx) * (real(1.0) - fy),
        fx * (real(1.0) - fy),
        (real(1.0) - fx) * fy,
        fx * fy,
    );
    var v = real(0.0);
    var a = real(0.0);
    for (var m = 0; m < 4; m = m + 1) {
        let c = cell(k, i0 + di[m], j0 + dj[m]);
        if c >= 0 {
            v = v + wt[m] * TEX[3u * u32(c)];
            a = a + wt[m];
        }
    }
    return vec2<real>(v, a);
}

struct Fallback {
    alpha: real,
    colour: vec3<f32>,
    z: real,
};

// warp.rs `offset_sample`: a ray stopped by the cap, or a hole, drawn from the enclosing frames'
// one-step offsets as the engine blend draws it, the depth read at the ray's point at display
// depth z_free (the last carving candidate); alpha, the colour's premultiplied sum and the
// display depth's, both to be divided by alpha.
fn offset_sample(lines: array<Line, MAX_SLOTS>, nf: u32, z_free: real) -> Fallback {
    var out: Fallback;
    out.alpha = real(0.0);
    out.colour = vec3<f32>(0.0);
    out.z = real(0.0);
    for (var s = 0u; s < nf; s = s + 1u) {
        let l = lines[s];
        let b = bilinear_depth(l.k, l.q + (l.a + l.c * z_free) * l.t);
        if b.y <= real(0.0) {
            continue;
        }
        let depth = b.x / b.y;
        let p = l.q + depth * l.t;
        let cov = bilinear_depth(l.k, p).y;
        if cov <= real(0.0) {
            continue;
        }
        let at = attributes_at(l.k, p);
        if at.found {
            let a = P[8u + 10u * s + 9u] * cov;
            out.alpha = out.alpha + a;
            out.colour = out.colour + shade(at.albedo, at.normal) * f32(a);
            out.z = out.z + a * (depth - l.a) / l.c;
        }
    }
    return out;
}

// The fragment of a ray drawn from the one-step offsets: discarded where the blended coverage
// is below ½ (warp.rs `ALPHA_TIE`), else the blended colour at the blended depth, written as
// every fragment's (0 at the front of the bounding sphere, 1 at its back).
fn offset_fragment(fb: Fallback) -> FsOut {
    if fb.alpha < real(0.5) - real(1e-6) {
        discard;
    }
    let zf = fb.z / fb.alpha;
    let d = clamp(f32((real(1.0) - zf) * real(0.5)), 0.0, 1.0);
    return fragment_out(vec4<f32>(fb.colour / f32(fb.alpha), 1.0), d);
}

@fragment
fn fs_main(in: VsOut) -> FsOut {
    let px = u32(in.pos.x);
    let py = u32(in.pos.y);
    let w = u32(P[4]);
    let frag = py * w + px;
    steps = 0u;
    // OrthoFrame::screen_at(i + ½, j + ½, w, w).
    let x = real(-1.0) + real(2.0) * (real(px) + real(0.5)) / P[4];
    let y = real(1.0) - real(2.0) * (real(py) + real(0.5)) / P[4];
    let r2 = x * x + y * y;
    if r2 >= real(1.0) {
        discard;
    }
    var flags = 4u;
    let zs = sqrt(real(1.0) - r2);
    let nf = U[0];
    let ne = U[1];
    var lines: array<Line, MAX_SLOTS>;
    for (var s = 0u; s < nf; s = s + 1u) {
        var l = line_of(s, x, y);
        l.lo = l.a - l.c * zs;
        l.hi = l.a + l.c * zs;
        if U[2] != 0u {
            // ConeBounds::interval at q: inside the frame, no event (the ray is free) or clip.
            let t = texel_coords(l.q);
            if t.x >= real(0.0) && t.x < size_f() && t.y >= real(0.0) && t.y < size_f() {
                let idx = (l.k * size_u() + u32(t.y)) * size_u() + u32(t.x);
                let code = CODE[idx];
                if (code & 2u) == 0u {
                    STEPS[2u * frag] = steps;
                    STEPS[2u * frag + 1u] = flags;
                    discard;
                }
                l.lo = max(l.lo, code_value((code >> 8u) & 255u));
                l.hi = min(l.hi, code_value((code >> 16u) & 255u));
            }
        }
        lines[s] = l;
    }
    // Frame slots in use: the enclosing frames, then each extra frame asked.
    var nl = nf;
    var z_cur = zs;
    var z_c = zs;
    var unresolved = true;
    var col = vec3<f32>(0.0);
    var wsum = real(0.0);
    var have_nearest = false;
    var nearest_gap = real(0.0);
    var nearest_col = vec3<f32>(0.0);
    loop {
        unresolved = true;
        for (var round = 0u; round < MAX_CARVE_ROUNDS; round = round + 1u) {
            if steps >= U[3] {
                // Spent: drawn from the enclosing frames' one-step offsets instead.
                flags = flags | 8u;
                STEPS[2u * frag] = steps;
                STEPS[2u * frag + 1u] = flags;
                return offset_fragment(offset_sample(lines, nf, z_cur));
            }
            // The deepest of the frames' next events below z_cur (display depth).
            // and the frame whose event it is (the first on ties).
            var deepest = P[2];
            var owner = 0u;
            for (var s = 0u; s < nl; s = s + 1u) {
                let l = lines[s];
                let p = at_p(l, z_cur);
                let zf = at_z(l, z_cur);
                steps = steps + 1u;
                var z = z_cur;
                if !hidden(l.k, p, zf) {
                    let e = first_event(l.k, l.q, l.t, min(zf, l.hi), l.lo);
                    if !e.found {
                        // Free from here on: the whole rest of the ray is free.
                        STEPS[2u * frag] = steps;
                        STEPS[2u * frag + 1u] = flags;
                        discard;
                    }
                    z = (e.z - l.a) / l.c;
                }
                if z < deepest {
                    deepest = z;
                    owner = s;
                }
            }
            z_c = deepest;
            // The candidate is hidden from its owner by construction; every other frame is
            // asked.
            var all_hidden = true;
            for (var s = 0u; s < nl; s = s + 1u) {
                if s == owner {
                    continue;
                }
                steps = steps + 1u;
                let l = lines[s];
                if !hidden(l.k, at_p(l, z_c - P[6]), at_z(l, z_c - P[6])) {
                    all_hidden = false;
                    break;
                }
            }
            if all_hidden {
                unresolved = false;
                break;
            }
            z_cur = z_c;
        }
        // Colour: the frames that see the point, by weight; else the nearest surface above it.
        col = vec3<f32>(0.0);
        wsum = real(0.0);
        have_nearest = false;
        for (var s = 0u; s < nl; s = s + 1u) {
            let l = lines[s];
            let p = at_p(l, z_c - P[6]);
            let zf = at_z(l, z_c - P[6]);
            let c = cell_at(l.k, p);
            let at = attributes_at(l.k, p);
            if c < 0 || !at.found {
                continue;
            }
            let h = height(u32(c), p);
            let shaded = shade(at.albedo, at.normal);
            let gap = h - zf;
            let weight = P[8u + 10u * s + 9u];
            if gap <= P[1] * pitch() {
                col = col + shaded * f32(weight);
                wsum = wsum + weight;
            }
            if !have_nearest || abs(gap) < nearest_gap {
                have_nearest = true;
                nearest_gap = abs(gap);
                nearest_col = shaded;
            }
        }
        if wsum > real(0.0) || nl >= nf + ne || steps >= U[3] {
            break;
        }
        // No frame asked sees the point: ask the next extra frame, its whole chord, carving
        // again from the candidate.
        var l = line_of(nl, x, y);
        l.lo = l.a - l.c * zs;
        l.hi = l.a + l.c * zs;
        lines[nl] = l;
        nl = nl + 1u;
        z_cur = z_c;
    }
    if unresolved {
        flags = flags | 2u;
    }
    if wsum <= real(0.0) && U[4] != 0u {
        // A hole drawn from the one-step offsets (warp.rs `HoleFill::Offsets`).
        if have_nearest {
            flags = flags | 1u;
        }
        STEPS[2u * frag] = steps;
        STEPS[2u * frag + 1u] = flags;
        return offset_fragment(offset_sample(lines, nf, z_c));
    }
    var colour: vec4<f32>;
    if wsum > real(0.0) {
        colour = vec4<f32>(col / f32(wsum), 1.0);
    } else if have_nearest {
        flags = flags | 1u;
        if nearest_gap > P[7] {
            // A hole deeper than the hole depth: taken as empty.
            STEPS[2u * frag] = steps;
            STEPS[2u * frag + 1u] = flags & 13u;
            discard;
        }
        colour = vec4<f32>(nearest_col, 1.0);
    } else {
        STEPS[2u * frag] = steps;
        STEPS[2u * frag + 1u] = flags & 12u;
        discard;
    }
    // Orthographic depth: 0 at the front of the bounding sphere, 1 at its back.
    let depth = clamp(f32((real(1.0) - z_c) * real(0.5)), 0.0, 1.0);
    STEPS[2u * frag] = steps;
    STEPS[2u * frag + 1u] = flags;
    return fragment_out(colour, depth);
}
