// The ellipsoid octree: the GPU twin of `altrep::ellipsoid::Octree::render_view_counted`
// (src/ellipsoid/octree/render.rs), in f32. Per fragment, the ray through the pixel centre is
// clipped to the cube [0, 2^depth]³ (voxel units) and marched front to back at fixed steps; each
// sample descends the tree to the drawn level (`find`), and the node's extinction and emitted
// colour, computed on the host per draw (they depend on the view direction only), are
// composited until the transmittance falls below 1e-4.

// Scalars: 0 image width (pixels), 1..3 window centre (voxel units), 4 half width, 5..7 screen
// right, 8..10 screen up, 11..13 direction toward the camera, 14 cube side 2^depth, 15 step ds,
// 16 image height.
@group(0) @binding(0) var<storage, read> F: array<f32>;
// Integers: 0 the level drawn, 1 the depth.
@group(0) @binding(1) var<storage, read> I: array<u32>;
// Per node: the index of its first child (0: a leaf; children are 8 consecutive nodes in octant
// order x + 2y + 4z).
@group(0) @binding(2) var<storage, read> CHILD: array<u32>;
// Per node: extinction per voxel length, then emitted linear RGB.
@group(0) @binding(3) var<storage, read> SHADE: array<vec4<f32>>;
// Per fragment: samples marched.
@group(0) @binding(4) var<storage, read_write> STEPS: array<u32>;

fn vec3_at(k: u32) -> vec3<f32> {
    return vec3<f32>(F[k], F[k + 1u], F[k + 2u]);
}

// render.rs `find`: the node answering at `p` for `level`, or −1 outside the cube.
fn find(p: vec3<f32>, level: u32) -> i32 {
    let side = F[14];
    for (var a = 0u; a < 3u; a = a + 1u) {
        if !(p[a] >= 0.0 && p[a] < side) {
            return -1;
        }
    }
    var index = 0u;
    var node_level = I[1];
    var origin = vec3<f32>(0.0);
    loop {
        let first = CHILD[index];
        if first == 0u || node_level <= level {
            return i32(index);
        }
        let half = f32(1u << (node_level - 1u));
        var octant = 0u;
        for (var a = 0u; a < 3u; a = a + 1u) {
            if p[a] >= origin[a] + half {
                octant = octant | (1u << a);
                origin[a] = origin[a] + half;
            }
        }
        index = first + octant;
        node_level = node_level - 1u;
    }
    return -1;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<u32> {
    let px = u32(in.pos.x);
    let py = u32(in.pos.y);
    let frag = py * u32(F[0]) + px;
    let x = -1.0 + 2.0 * (f32(px) + 0.5) / F[0];
    let y = 1.0 - 2.0 * (f32(py) + 0.5) / F[16];
    let dir = vec3_at(11u);
    let p0 = vec3_at(1u) + F[4] * (x * vec3_at(5u) + y * vec3_at(8u));
    let side = F[14];
    var s_min = -3.0e38;
    var s_max = 3.0e38;
    for (var a = 0u; a < 3u; a = a + 1u) {
        if dir[a] == 0.0 {
            if !(p0[a] >= 0.0 && p0[a] <= side) {
                s_min = 1.0;
                s_max = 0.0;
            }
            continue;
        }
        let t0 = -p0[a] / dir[a];
        let t1 = (side - p0[a]) / dir[a];
        s_min = max(s_min, min(t0, t1));
        s_max = min(s_max, max(t0, t1));
    }
    let ds = F[15];
    var steps = 0u;
    if s_max > s_min {
        steps = u32(max(ceil((s_max - s_min) / ds - 0.5), 0.0));
    }
    var t = 1.0;
    var c = vec3<f32>(0.0);
    var taken = 0u;
    for (var k = 0u; k < steps; k = k + 1u) {
        taken = taken + 1u;
        let p = p0 + (s_max - (f32(k) + 0.5) * ds) * dir;
        let index = find(p, I[0]);
        if index < 0 {
            continue;
        }
        let shade = SHADE[u32(index)];
        if shade.x <= 0.0 {
            continue;
        }
        let alpha = 1.0 - exp(-shade.x * ds);
        c = c + t * alpha * shade.yzw;
        t = t * (1.0 - alpha);
        if t < 1e-4 {
            break;
        }
    }
    STEPS[frag] = taken;
    return colour_bits(vec4<f32>(c, 1.0 - t));
}
