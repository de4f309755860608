// Slices: the GPU twin of `altrep::slices::render_object` (src/slices/object.rs) and, for a tile
// over a ground patch, of `altrep::slices::render_slices` (src/slices/render.rs), at one sample
// per pixel, in f32. Per fragment, the ray through the pixel centre is clipped to the object's box
// or the patch of tiles, and the slices of the chosen stack it crosses are composited nearest
// first, each read with trilinear 2D filtering (the two 2D levels and their blend weight are the
// host's, constant over a draw) and its opacity raised to the path length (src/slices/volume.rs
// `rescale_thickness`). Conventions: src/slices/mod.rs and docs/design.md §9.4.

// Scalars: 0 screen size (pixels), 1..3 frame centre minus the box's lower corner, 4 frame radius,
// 5..7 screen right, 8..10 screen up, 11..13 direction toward the camera, 14..16 box extent,
// 17 slice spacing h, 18 opacity ratio 1/|v_axis|, 19 blend weight of the coarser 2D level,
// 20 largest alpha (volume.rs `MAX_ALPHA`), 21..23 extent of the box rays are clipped to (the
// object's box, or the patch of tiles).
@group(0) @binding(0) var<storage, read> F: array<f32>;
// Integers: 0 slice axis, 1 and 2 the plane's u and v axes, 3 slices in the stack, 4 offset of
// slice 0's texels (the viewer's side), 5 texels per slice (all 2D levels), 6..8 offset in a slice,
// width and height of the finer 2D level read, 9..11 the same of the coarser, 12 and 13 whether u
// and v repeat (else they clamp), 14 and 15 whether the patch is unbounded along x and z, 16
// whether slice indices wrap (a tile's x and z stacks: render.rs `shade_stack`).
@group(0) @binding(1) var<storage, read> I: array<u32>;
// Premultiplied linear RGBA texels of every slice of every stored stack and side.
@group(0) @binding(2) var<storage, read> TX: array<vec4<f32>>;
// Per fragment: slices read; whether the ray crossed a slice (1) or not (0).
@group(0) @binding(3) var<storage, read_write> STEPS: array<u32>;

fn vec3_at(k: u32) -> vec3<f32> {
    return vec3<f32>(F[k], F[k + 1u], F[k + 2u]);
}

// pyramid/filter.rs `wrap_index` for Clamp and Repeat.
fn wrap(i: i32, n: u32, repeat: bool) -> u32 {
    let m = i32(n);
    if repeat {
        return u32(((i % m) + m) % m);
    }
    return u32(clamp(i, 0, m - 1));
}

// pyramid/mip.rs `bilinear_into` of the level at `offset` (`w × h` texels) of one slice.
fn bilinear(offset: u32, w: u32, h: u32, u: f32, v: f32) -> vec4<f32> {
    let s = u * f32(w) - 0.5;
    let r = v * f32(h) - 0.5;
    let i0 = floor(s);
    let j0 = floor(r);
    let fx = s - i0;
    let fy = r - j0;
    let ru = I[12] != 0u;
    let rv = I[13] != 0u;
    let ia0 = wrap(i32(i0), w, ru);
    let ia1 = wrap(i32(i0) + 1, w, ru);
    let ja0 = wrap(i32(j0), h, rv);
    let ja1 = wrap(i32(j0) + 1, h, rv);
    var out = vec4<f32>(0.0);
    out = out + ((1.0 - fx) * (1.0 - fy)) * TX[offset + ja0 * w + ia0];
    out = out + (fx * (1.0 - fy)) * TX[offset + ja0 * w + ia1];
    out = out + ((1.0 - fx) * fy) * TX[offset + ja1 * w + ia0];
    out = out + (fx * fy) * TX[offset + ja1 * w + ia1];
    return out;
}

// The parameter interval of the line o + t·dir inside the box [0, extent] (object.rs `box_span`);
// `x > y` when it misses.
// An axis flagged unbounded (I[14] for x, I[15] for z) is not clipped.
fn box_span(o: vec3<f32>, dir: vec3<f32>, extent: vec3<f32>) -> vec2<f32> {
    var t0 = -3.0e38;
    var t1 = 3.0e38;
    for (var a = 0u; a < 3u; a = a + 1u) {
        if (a == 0u && I[14] != 0u) || (a == 2u && I[15] != 0u) {
            continue;
        }
        if abs(dir[a]) < 1e-15 {
            if o[a] < 0.0 || o[a] > extent[a] {
                return vec2<f32>(1.0, 0.0);
            }
            continue;
        }
        let ta = -o[a] / dir[a];
        let tb = (extent[a] - o[a]) / dir[a];
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    return vec2<f32>(t0, t1);
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<u32> {
    let px = u32(in.pos.x);
    let py = u32(in.pos.y);
    let size = F[0];
    let frag = py * u32(size) + px;
    STEPS[2u * frag] = 0u;
    STEPS[2u * frag + 1u] = 0u;
    let x = -1.0 + (f32(px) + 0.5) * 2.0 / size;
    let y = 1.0 - (f32(py) + 0.5) * 2.0 / size;
    let o = vec3_at(1u) + F[4] * (x * vec3_at(5u) + y * vec3_at(8u));
    let dir = -vec3_at(11u);
    let extent = vec3_at(14u);
    let span = box_span(o, dir, vec3_at(21u));
    let i = I[0];
    let d_i = dir[i];
    if span.x > span.y || abs(d_i) < 1e-12 {
        return colour_bits(vec4<f32>(0.0));
    }
    let h = F[17];
    let qa = o[i] + span.x * d_i;
    let qb = o[i] + span.y * d_i;
    let lo = min(qa, qb);
    let hi = max(qa, qb);
    let count = i32(I[3]);
    let wraps = I[16] != 0u;
    var m_lo = i32(ceil(lo / h - 0.5));
    var m_hi = i32(floor(hi / h - 0.5));
    if !wraps {
        m_lo = max(m_lo, 0);
        m_hi = min(m_hi, count - 1);
    }
    if m_lo > m_hi {
        return colour_bits(vec4<f32>(0.0));
    }
    let ua = I[1];
    let va = I[2];
    let ratio = F[18];
    let blend = F[19];
    var acc = vec4<f32>(0.0);
    var reads = 0u;
    for (var s = 0; s <= m_hi - m_lo; s = s + 1) {
        var m = m_hi - s;
        if d_i > 0.0 {
            m = m_lo + s;
        }
        let t = ((f32(m) + 0.5) * h - o[i]) / d_i;
        let hit = o + t * dir;
        let u = hit[ua] / extent[ua];
        let v = hit[va] / extent[va];
        let base = I[4] + u32(((m % count) + count) % count) * I[5];
        var sample = bilinear(base + I[6], I[7], I[8], u, v);
        if blend > 0.0 {
            let b = bilinear(base + I[9], I[10], I[11], u, v);
            sample = (1.0 - blend) * sample + blend * b;
        }
        reads = reads + 1u;
        // volume.rs `rescale_thickness`.
        let a = sample.w;
        var c = vec4<f32>(0.0);
        if a > 0.0 {
            let a2 = 1.0 - pow(1.0 - min(a, F[20]), ratio);
            let k = a2 / a;
            c = vec4<f32>(sample.xyz * k, a2);
        }
        // render.rs `accumulate`.
        acc = acc + (1.0 - acc.w) * c;
        if acc.w > 1.0 - 1e-6 {
            break;
        }
    }
    STEPS[2u * frag] = reads;
    STEPS[2u * frag + 1u] = 1u;
    return colour_bits(acc);
}
