// Ingest from a caller's texture into the f32 grey image (0..255 scale).
//
// Every accepted format holds 8-bit channels. The shader first recovers the
// stored bytes exactly: a unorm channel is `round(c * 255)`; an sRGB channel,
// which textureLoad returns linearised, is re-encoded with the sRGB transfer
// function first. Grey formats take the red byte; colour formats reduce the
// R, G, B bytes to BT.601 luma in integer arithmetic, rounded to the nearest
// integer (halves up), so the result equals the grey byte the CPU twin
// (`gray_from_texels`) gives for the same texels. Bgra8 textures need no
// swizzle here: textureLoad returns their channels in RGBA order.
// Kept in sync with `IngestUniform` and `TexelKind` in src/early/ingest.rs.

struct Params {
    width: u32,
    height: u32,
    kind: u32,
    _pad: u32,
}

// `Params.kind`: how texels become bytes.
const KIND_GRAY: u32 = 0u;
const KIND_COLOUR: u32 = 1u;
const KIND_SRGB_COLOUR: u32 = 2u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> dst: array<f32>;
@group(0) @binding(2) var frame: texture_2d<f32>;

// A unorm channel back to its byte.
fn unorm_byte(c: f32) -> u32 {
    return u32(round(clamp(c, 0.0, 1.0) * 255.0));
}

// A linearised sRGB channel back to its stored byte (the sRGB encoding,
// IEC 61966-2-1).
fn srgb_byte(c: f32) -> u32 {
    let x = clamp(c, 0.0, 1.0);
    var e = 12.92 * x;
    if (x > 0.0031308) {
        e = 1.055 * pow(x, 1.0 / 2.4) - 0.055;
    }
    return u32(round(clamp(e, 0.0, 1.0) * 255.0));
}

// BT.601 luma of three bytes, rounded: (299 r + 587 g + 114 b + 500) / 1000.
fn luma_byte(r: u32, g: u32, b: u32) -> u32 {
    return (299u * r + 587u * g + 114u * b + 500u) / 1000u;
}

@compute @workgroup_size(16, 16)
fn from_texture(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let c = textureLoad(frame, vec2<i32>(id.xy), 0);
    var v: u32;
    if (params.kind == KIND_GRAY) {
        v = unorm_byte(c.r);
    } else if (params.kind == KIND_COLOUR) {
        v = luma_byte(unorm_byte(c.r), unorm_byte(c.g), unorm_byte(c.b));
    } else {
        v = luma_byte(srgb_byte(c.r), srgb_byte(c.g), srgb_byte(c.b));
    }
    dst[id.y * params.width + id.x] = f32(v);
}
