// Pyramid lookups on a minified textured plane: the GPU twins of
// `altrep::pyramid::{Pyramid::sample_grad, RipMap::sample_grad, FipMap::sample_into}` with the
// per-pixel mip/rip/fip decision (`FipMap::decide`), and of the camera of
// `altrep::pyramid::truth` (src/pyramid/truth.rs). Level choice and filtering are done by hand from
// explicit derivatives (no hardware sampler, whose LOD rule and filter weights differ between
// implementations), in the CPU's order of operations:
//
// * bilinear: s = u·w − ½, i0 = ⌊s⌋, fx = s − i0 (same for t), weights (1−fx)(1−fy), fx(1−fy),
//   (1−fx)fy, fx·fy accumulated in that order; texel indices wrapped per axis (clamp, repeat,
//   mirror as `filter::wrap_index`);
// * mip: λ = log2 max(√((u_x w)² + (v_x h)²), √((u_y w)² + (v_y h)²)) (Heckbert's D, level-0 sizes
//   of the first stored level), clamped to [0, n − 1]; the level above is blended in when its
//   weight f = λ − ⌊λ⌋ is positive;
// * rip: λ_u = log2(w·max(|u_x|, |u_y|)), λ_v = log2(h·max(|v_x|, |v_y|)), each clamped; the four
//   nearest levels blended bilinearly in (λ_u, λ_v), levels of zero weight skipped;
// * fip: the direction to the camera in the polygon frame decides mip, rip or one sheared ripmap,
//   whose stored coordinates are (u/q, v + c·u) (V shear) or (u + c·v, v/q) (U shear).
//
// Everything runs in f32. The plane hit is computed in a cancellation-free form (offset from the
// target point) so that f32 keeps the texture coordinates of far, grazing pixels.

// Floats: 0..2 back (unit vector from the target to the camera), 3..5 screen right, 6..8 screen
// up, 9 camera distance, 10 u of the target, 11 v of the target, 12 pixel angle, 13 half the
// image side (pixels), 14 mip_max_tilt_deg, 15 fip_min_tilt_deg, 16 rip_max_skew_deg.
@group(0) @binding(0) var<storage, read> F: array<f32>;
// Integers: 0 sampler (0 mip, 1 rip, 2 fip), 1 image side (pixels), 2 channels, 3 wrap u,
// 4 wrap v (0 clamp, 1 repeat, 2 mirror), 5 mip base (index into LV), 6 mip levels, 7 rip base,
// 8 rip levels along u, 9 rip levels along v, 10 number of shears.
@group(0) @binding(1) var<storage, read> I: array<u32>;
// Level table: (first texel in TX, width, height, unused).
@group(0) @binding(2) var<storage, read> LV: array<vec4<u32>>;
// Texels of every level, row-major, channels padded to 4 with 0.
@group(0) @binding(3) var<storage, read> TX: array<vec4<f32>>;
// Per shear: (c, q, unused, unused): the shear value and its period.
@group(0) @binding(4) var<storage, read> SHF: array<vec4<f32>>;
// Per shear: (rip base, levels along u, levels along v, axis: 0 V, 1 U).
@group(0) @binding(5) var<storage, read> SHI: array<vec4<u32>>;
// Per fragment: scheme (1 mip, 2 rip, 3 + i fip shear i; 0 where the ray missed the plane) and
// the number of bilinear lookups.
@group(0) @binding(6) var<storage, read_write> STEPS: array<u32>;

const PI: f32 = 3.14159265358979;
const HALF_PI: f32 = 1.57079632679490;

var<private> lookups: u32;

fn wrap_index(mode: u32, i: i32, n: i32) -> i32 {
    if mode == 0u {
        return clamp(i, 0, n - 1);
    }
    if mode == 1u {
        return ((i % n) + n) % n;
    }
    let m = 2 * n;
    let k = ((i % m) + m) % m;
    if k < n {
        return k;
    }
    return m - 1 - k;
}

fn texel(l: vec4<u32>, i: i32, j: i32) -> vec4<f32> {
    return TX[l.x + u32(j) * l.y + u32(i)];
}

// `Pyramid::bilinear_into` on level table entry `level`.
fn bilinear(level: u32, u: f32, v: f32) -> vec4<f32> {
    lookups += 1u;
    let l = LV[level];
    let w = i32(l.y);
    let h = i32(l.z);
    let s = u * f32(l.y) - 0.5;
    let r = v * f32(l.z) - 0.5;
    let i0f = floor(s);
    let j0f = floor(r);
    let fx = s - i0f;
    let fy = r - j0f;
    let i0 = i32(i0f);
    let j0 = i32(j0f);
    let ia = wrap_index(I[3], i0, w);
    let ib = wrap_index(I[3], i0 + 1, w);
    let ja = wrap_index(I[4], j0, h);
    let jb = wrap_index(I[4], j0 + 1, h);
    var out = vec4<f32>(0.0);
    out += ((1.0 - fx) * (1.0 - fy)) * texel(l, ia, ja);
    out += (fx * (1.0 - fy)) * texel(l, ib, ja);
    out += ((1.0 - fx) * fy) * texel(l, ia, jb);
    out += (fx * fy) * texel(l, ib, jb);
    return out;
}

// `Pyramid::lod`: Heckbert's D in texels of the first stored level.
fn mip_lod(base: u32, d: vec4<f32>) -> f32 {
    let w = f32(LV[base].y);
    let h = f32(LV[base].z);
    let dx = sqrt((d.x * w) * (d.x * w) + (d.y * h) * (d.y * h));
    let dy = sqrt((d.z * w) * (d.z * w) + (d.w * h) * (d.w * h));
    return log2(max(dx, dy));
}

// `Pyramid::trilinear`.
fn mip_sample(base: u32, n: u32, u: f32, v: f32, lod: f32) -> vec4<f32> {
    var l = 0.0;
    if lod > 0.0 {
        l = min(lod, f32(n - 1u));
    }
    let l0f = floor(l);
    let l0 = u32(l0f);
    let f = l - l0f;
    var a = bilinear(base + l0, u, v);
    if f > 0.0 {
        let b = bilinear(base + min(l0 + 1u, n - 1u), u, v);
        a = (1.0 - f) * a + f * b;
    }
    return a;
}

// `RipMap::lod`.
fn rip_lod(base: u32, d: vec4<f32>) -> vec2<f32> {
    let du = f32(LV[base].y) * max(abs(d.x), abs(d.z));
    let dv = f32(LV[base].z) * max(abs(d.y), abs(d.w));
    return vec2<f32>(log2(du), log2(dv));
}

fn split(lod: f32, n: u32) -> vec2<f32> {
    var l = 0.0;
    if lod > 0.0 {
        l = min(lod, f32(n - 1u));
    }
    let i = floor(l);
    return vec2<f32>(i, l - i);
}

// `RipMap::sample_lod_into`: level (l_u, l_v) is entry base + l_v·nu + l_u (clamped per axis).
fn rip_sample(base: u32, nu: u32, nv: u32, u: f32, v: f32, lod: vec2<f32>) -> vec4<f32> {
    let su = split(lod.x, nu);
    let sv = split(lod.y, nv);
    let iu = u32(su.x);
    let iv = u32(sv.x);
    var out = vec4<f32>(0.0);
    for (var a = 0u; a < 2u; a++) {
        let wu = select(1.0 - su.y, su.y, a == 1u);
        for (var b = 0u; b < 2u; b++) {
            let wv = select(1.0 - sv.y, sv.y, b == 1u);
            let w = wu * wv;
            if w <= 0.0 {
                continue;
            }
            let lu = min(iu + a, nu - 1u);
            let lv = min(iv + b, nv - 1u);
            out += w * bilinear(base + lv * nu + lu, u, v);
        }
    }
    return out;
}

// `Shear::residual`.
fn residual(i: u32, phi: f32) -> f32 {
    let c = SHF[i].x;
    var du = cos(phi);
    var dv = sin(phi);
    var target_angle = 0.0;
    if SHI[i].w == 0u {
        dv = dv + c * du;
    } else {
        du = du + c * dv;
        target_angle = HALF_PI;
    }
    let a = atan2(dv, du);
    let ang = a - floor(a / PI) * PI;
    let d = abs(ang - target_angle);
    return min(d, PI - d);
}

// `fip::decide`: 1 mip, 2 rip, 3 + i shear i.
fn decide(dir: vec3<f32>) -> u32 {
    let n = length(dir);
    if !(n > 0.0) {
        return 1u;
    }
    let tilt = degrees(acos(clamp(abs(dir.y) / n, 0.0, 1.0)));
    if tilt <= F[14] {
        return 1u;
    }
    let phi = atan2(dir.z, dir.x);
    let a = phi - floor(phi / HALF_PI) * HALF_PI;
    let skew = degrees(min(a, HALF_PI - a));
    let ns = I[10];
    if skew <= F[16] || tilt < F[15] || ns == 0u {
        return 2u;
    }
    var best = 0u;
    var best_r = residual(0u, phi);
    for (var i = 1u; i < ns; i++) {
        let r = residual(i, phi);
        if r < best_r {
            best = i;
            best_r = r;
        }
    }
    return 3u + best;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<u32> {
    let px = u32(in.pos.x);
    let py = u32(in.pos.y);
    let side = I[1];
    let frag = py * side + px;
    lookups = 0u;
    // Screen offset of the pixel centre from the image centre (truth.rs `footprints`).
    let sx = in.pos.x - F[13];
    let sy = in.pos.y - F[13];
    let back = vec3<f32>(F[0], F[1], F[2]);
    let right = vec3<f32>(F[3], F[4], F[5]);
    let up = vec3<f32>(F[6], F[7], F[8]);
    let dist = F[9];
    let alpha = F[12];
    let e = alpha * (sx * right + sy * up);
    let d = e - back;
    if d.z >= 0.0 {
        STEPS[2u * frag] = 0u;
        STEPS[2u * frag + 1u] = 0u;
        return colour_bits(vec4<f32>(0.0));
    }
    let cz = back.z - e.z;
    let t = dist * back.z / cz;
    // Hit minus target: (dist − t)·back + t·e, with dist − t = −dist·e_z/(cos θ − e_z).
    let off = (-(dist * e.z) / cz) * back + t * e;
    let u = F[10] + off.x;
    let v = F[11] + off.y;
    // ∂q/∂s = t·α·(a − (a_z/d_z)·d) per screen axis a.
    let qx = t * alpha * (right - (right.z / d.z) * d);
    let qy = t * alpha * (up - (up.z / d.z) * d);
    let dv = vec4<f32>(qx.x, qx.y, qy.x, qy.y);
    let to_cam = normalize(dist * back - off);
    var scheme = 1u;
    if I[0] == 1u {
        scheme = 2u;
    } else if I[0] == 2u {
        scheme = decide(vec3<f32>(to_cam.x, to_cam.z, to_cam.y));
    }
    var s = vec4<f32>(0.0);
    if scheme == 1u {
        s = mip_sample(I[5], I[6], u, v, mip_lod(I[5], dv));
    } else if scheme == 2u {
        s = rip_sample(I[7], I[8], I[9], u, v, rip_lod(I[7], dv));
    } else {
        let k = scheme - 3u;
        let c = SHF[k].x;
        let q = SHF[k].y;
        let sh = SHI[k];
        var st = vec2<f32>(0.0);
        var sd = vec4<f32>(0.0);
        if sh.w == 0u {
            st = vec2<f32>(u / q, v + c * u);
            sd = vec4<f32>(dv.x / q, dv.y + c * dv.x, dv.z / q, dv.w + c * dv.z);
        } else {
            st = vec2<f32>(u + c * v, v / q);
            sd = vec4<f32>(dv.x + c * dv.y, dv.y / q, dv.z + c * dv.w, dv.w / q);
        }
        s = rip_sample(sh.x, sh.y, sh.z, st.x, st.y, rip_lod(sh.x, sd));
    }
    STEPS[2u * frag] = scheme;
    STEPS[2u * frag + 1u] = lookups;
    let ch = I[2];
    var out = vec4<f32>(s.x, s.x, s.x, 1.0);
    if ch >= 2u {
        out.y = s.y;
    }
    if ch >= 3u {
        out.z = s.z;
    }
    if ch == 4u {
        out.w = s.w;
    }
    return colour_bits(out);
}
