// The cell's camera: vertices already in the camera frame (x right, y down, z forward) via each
// object's camera_from_object; a pinhole projection; diffuse + Blinn-Phong + sheen shading with
// directional lights; oil stains and dirt as soft dark blobs on stainable surfaces.
//
// Written for software rasterisers (llvmpipe, lavapipe), which run eight fragments in lockstep
// and pay for every loop iteration and both sides of every branch: the light count is a pipeline
// constant (the loop unrolls), only the stainable triangles (end faces) run the stain loop
// (fs_stained), and per-triangle material values are not interpolated.

const MAX_STAINS: u32 = 32u;

// Directional lights in use (at most 4); each count gets its own pipeline.
override LIGHT_COUNT: u32 = 0u;

struct Globals {
    clip_from_camera: mat4x4<f32>,
    ambient: vec4<f32>,
    // Unit vector from the surface towards each light, camera frame; w unused.
    light_dir: array<vec4<f32>, 4>,
    light_rgb: array<vec4<f32>, 4>,
    // Stain blob centre (camera frame) and radius, m.
    stain_centre: array<vec4<f32>, 32>,
    // x: transmission (the share of light the stain lets through), y: soft edge share.
    stain_params: array<vec4<f32>, 32>,
    // y: stain blobs; x, z, w unused.
    counts: vec4<u32>,
};

struct Object {
    camera_from_object: mat4x4<f32>,
    id: vec4<u32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;
@group(1) @binding(0) var<uniform> object: Object;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) albedo: vec3<f32>,
    // x: specular, y: shininess, z: sheen.
    @location(3) surface: vec3<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    // A triangle's corners share one material.
    @location(2) @interpolate(flat) albedo: vec3<f32>,
    @location(3) @interpolate(flat) surface: vec3<f32>,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    let p = object.camera_from_object * vec4<f32>(v.position, 1.0);
    out.clip = globals.clip_from_camera * p;
    out.position = p.xyz;
    out.normal = (object.camera_from_object * vec4<f32>(v.normal, 0.0)).xyz;
    out.albedo = v.albedo;
    out.surface = v.surface;
    return out;
}

// Lit colour of a fragment of the given albedo.
fn shade(in: VertexOut, front: bool, albedo: vec3<f32>) -> vec4<f32> {
    var n = normalize(in.normal);
    if (!front) {
        n = -n;
    }
    let view = normalize(-in.position);
    var colour = albedo * globals.ambient.rgb;
    for (var i = 0u; i < LIGHT_COUNT; i = i + 1u) {
        let l = globals.light_dir[i].xyz;
        let lambert = max(dot(n, l), 0.0);
        let half_vector = normalize(l + view);
        var spec = 0.0;
        if (lambert > 0.0) {
            spec = in.surface.x * pow(max(dot(n, half_vector), 0.0), in.surface.y);
        }
        colour = colour + globals.light_rgb[i].rgb * (albedo * lambert + vec3<f32>(spec));
    }
    let grazing = 1.0 - abs(dot(n, view));
    colour = colour + vec3<f32>(in.surface.z * grazing * grazing);
    return vec4<f32>(clamp(colour, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0);
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return shade(in, front, in.albedo);
}

// Stainable surfaces: the albedo darkened by every stain blob that covers the fragment.
@fragment
fn fs_stained(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var albedo = in.albedo;
    for (var i = 0u; i < min(globals.counts.y, MAX_STAINS); i = i + 1u) {
        let c = globals.stain_centre[i];
        let d = length(in.position - c.xyz) / c.w;
        let soft = globals.stain_params[i].y;
        let cover = 1.0 - smoothstep(1.0 - soft, 1.0, d);
        albedo = albedo * mix(1.0, globals.stain_params[i].x, cover);
    }
    return shade(in, front, albedo);
}

@fragment
fn fs_id(in: VertexOut) -> @location(0) u32 {
    return object.id.x;
}
