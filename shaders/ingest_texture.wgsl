// Ingest from a caller's texture (R8Unorm or Rgba8Unorm) into the f32 grey
// image (0..255 scale). RGBA is reduced to luma with the BT.601 weights of
// `crate::image::luma`. Kept in sync with src/early/ingest.rs.

struct Params {
    width: u32,
    height: u32,
    rgba: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> dst: array<f32>;
@group(0) @binding(2) var frame: texture_2d<f32>;

@compute @workgroup_size(16, 16)
fn from_texture(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let c = textureLoad(frame, vec2<i32>(id.xy), 0);
    // Unorm → 0..255 integers exactly.
    let r = round(c.r * 255.0);
    var v = r;
    if (params.rgba != 0u) {
        let g = round(c.g * 255.0);
        let b = round(c.b * 255.0);
        v = 0.299 * r + 0.587 * g + 0.114 * b;
    }
    dst[id.y * params.width + id.x] = v;
}
