// Shared by every display shader: `shader::compose` puts this file before each shader's own
// code. It holds the precision alias, the full-screen quad, the CPU's diffuse shading and the
// fragment outputs, so each exists once.

// `real` is f32 (the production shaders) or f64 (the exact twins used by the step-count tests
// when the adapter has SHADER_F64); `shader::compose` replaces this line.
alias real = f32;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    // The impostor's quad (or the textured plane's screen) fills the viewport: two triangles.
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    var out: VsOut;
    out.pos = vec4<f32>(corners[vi], 0.0, 1.0);
    return out;
}

// glam's `Vec3::normalize_or_zero`: the zero vector where the length is zero or not finite.
fn normalize_or_zero(n: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / sqrt(dot(n, n));
    var nn = vec3<f32>(0.0);
    if rcp > 0.0 && rcp < 3.0e38 {
        nn = n * rcp;
    }
    return nn;
}

// The CPU's diffuse shading (`altrep_data_gen::Light`): ambient plus Lambert,
// `albedo · (a + (1 − a)·max(n·l, 0))`, with `light` = (unit direction xyz, ambient a) and a unit
// (or zero) normal.
fn diffuse(albedo: vec3<f32>, unit_normal: vec3<f32>, light: vec4<f32>) -> vec3<f32> {
    let amb = light.w;
    return albedo * (amb + (1.0 - amb) * max(dot(unit_normal, light.xyz), 0.0));
}

// The colour's f32 bits: the colour target is `Rgba32Uint`, which every backend (GL included)
// can render to, and which keeps the shader's f32 values exactly for the read-back.
fn colour_bits(colour: vec4<f32>) -> vec4<u32> {
    return bitcast<vec4<u32>>(colour);
}

// Fragment outputs of the impostors: the colour's bits, the depth's bits in an `R32Uint` target
// (depth textures cannot be copied to buffers on every backend), and the depth itself, which the
// depth test uses.
struct FsOut {
    @location(0) colour: vec4<u32>,
    @location(1) depth_bits: u32,
    @builtin(frag_depth) depth: f32,
};

// The outputs of a drawn fragment: premultiplied linear `colour` at orthographic `depth`
// (0 nearest, 1 farthest).
fn fragment_out(colour: vec4<f32>, depth: f32) -> FsOut {
    var out: FsOut;
    out.colour = colour_bits(colour);
    out.depth_bits = bitcast<u32>(depth);
    out.depth = depth;
    return out;
}
