// Ingest: turn a frame of 8-bit grey bytes into the f32 grey image (0..255
// scale) every other stage reads. Textures go through ingest_texture.wgsl.
// Kept in sync with `IngestUniform` in src/early/ingest.rs.

struct Params {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> dst: array<f32>;

// 8-bit grey bytes, packed four to a u32 (little-endian), row-major.
@group(0) @binding(2) var<storage, read> packed: array<u32>;

@compute @workgroup_size(16, 16)
fn from_bytes(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    // Layer id.z: its plane of f32 and its bytes, padded to whole words.
    let area = params.width * params.height;
    let i = id.y * params.width + id.x;
    let word = id.z * ((area + 3u) / 4u) + i / 4u;
    let byte = (packed[word] >> (8u * (i % 4u))) & 0xffu;
    dst[id.z * area + i] = f32(byte);
}
