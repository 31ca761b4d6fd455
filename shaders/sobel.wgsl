// Sobel 3×3 gradient with clamp-to-edge borders (000 eq. 2, 002 §2.3).
// One entry point writes all five planes: gx, gy, magnitude, gradient
// direction atan2(gy, gx) in (−π, π], and the edge orientation θ of 000
// eq. 2 in [0, π). The angle conventions and guards are documented in
// src/early/sobel.rs and mirrored there step by step. PI, HALF_PI and
// fast_atan_quotient come from shaders/angle.wgsl, appended to this file when the
// module is built. Kept in sync with `SobelUniform` in src/early/sobel.rs.
// Stacked images (a stack of layers, each width×height after the one
// before) are one dispatch: the grid's z is the layer (`id.z`).

struct Params {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> src: array<f32>;
@group(0) @binding(2) var<storage, read_write> gx_out: array<f32>;
@group(0) @binding(3) var<storage, read_write> gy_out: array<f32>;
@group(0) @binding(4) var<storage, read_write> magnitude_out: array<f32>;
@group(0) @binding(5) var<storage, read_write> direction_out: array<f32>;
@group(0) @binding(6) var<storage, read_write> theta_out: array<f32>;

@compute @workgroup_size(16, 16)
fn sobel(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = params.width;
    let h = params.height;
    if (id.x >= w || id.y >= h) {
        return;
    }
    // Clamp-to-edge neighbours: columns xl, xc, xr of rows up, mid, down.
    let xc = id.x;
    let xl = select(xc - 1u, 0u, xc == 0u);
    let xr = min(xc + 1u, w - 1u);
    let base = id.z * h * w;
    let up = base + select(id.y - 1u, 0u, id.y == 0u) * w;
    let mid = base + id.y * w;
    let down = base + min(id.y + 1u, h - 1u) * w;

    // gx = [−1 0 1; −2 0 2; −1 0 1]: vertical [1 2 1] sums of the right
    // column minus the left one.
    let sum_l = (src[up + xl] + 2.0 * src[mid + xl]) + src[down + xl];
    let sum_r = (src[up + xr] + 2.0 * src[mid + xr]) + src[down + xr];
    let gx = sum_r - sum_l;
    // gy = gxᵀ (y down): [1 2 1] sum across columns of down − up differences.
    let d_l = src[down + xl] - src[up + xl];
    let d_c = src[down + xc] - src[up + xc];
    let d_r = src[down + xr] - src[up + xr];
    let gy = (d_l + 2.0 * d_c) + d_r;

    let magnitude = sqrt(gx * gx + gy * gy);

    // Angles from one atan of gy/gx; guarded so that atan2(0, 0) never occurs.
    var direction = 0.0;
    var theta = HALF_PI;
    if (gx != 0.0) {
        let a = fast_atan_quotient(gy, gx);
        // 000 eq. 2: θ = atan(∇y/∇x) + π/2, folded into [0, π).
        theta = a + HALF_PI;
        if (theta < 0.0 || theta >= PI) {
            theta = 0.0;
        }
        if (gx > 0.0) {
            direction = a;
        } else if (gy >= 0.0) {
            direction = a + PI;
        } else {
            direction = a - PI;
            if (direction <= -PI) {
                direction = PI;
            }
        }
    } else if (gy != 0.0) {
        direction = select(-HALF_PI, HALF_PI, gy > 0.0);
        theta = 0.0;
    }

    let i = mid + xc;
    gx_out[i] = gx;
    gy_out[i] = gy;
    magnitude_out[i] = magnitude;
    direction_out[i] = direction;
    theta_out[i] = theta;
}
