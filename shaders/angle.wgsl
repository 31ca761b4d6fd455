// Arctangents by Hastings' odd degree-15 polynomial, shared by the shaders
// that include it (sobel, zero_crossing: see `includes` in their ShaderDef).
// The CPU twin is src/early/angle.rs (`fast_atan`, `fast_atan_quotient`,
// `fast_atan2`): the same operations in the same order, so both twins round
// alike, and atan2(0, 0) is defined (0), unlike the builtin's.

const PI: f32 = 3.14159265358979;
const HALF_PI: f32 = 1.57079632679490;

// atan(a) for a in [0, 1]: the polynomial in s = a² by Estrin's scheme,
// pairs of coefficients first, then the pairs in s², then the halves in s⁴.
fn atan_unit(a: f32) -> f32 {
    let s = a * a;
    let s2 = s * s;
    let s4 = s2 * s2;
    let q0 = -0.33329856 * s + 0.99999933;
    let q1 = -0.13908534 * s + 0.19946536;
    let q2 = -0.055909886 * s + 0.096420044;
    let q3 = -0.004054058 * s + 0.021861229;
    let p = (q1 * s2 + q0) + (q3 * s2 + q2) * s4;
    return p * a;
}

// atan(t) in (−π/2, π/2) for any finite t: atan(t) = π/2 − atan(1/t) beyond 1.
fn fast_atan(t: f32) -> f32 {
    let at = abs(t);
    let invert = at > 1.0;
    var a = at;
    if (invert) {
        a = 1.0 / at;
    }
    var r = atan_unit(a);
    if (invert) {
        r = HALF_PI - r;
    }
    return select(r, -r, t < 0.0);
}

// atan(y / x) in [−π/2, π/2] for x != 0 with one division: the polynomial of
// min(|x|, |y|) / max(|x|, |y|), reflected where |y| > |x|, negative where x
// and y differ in sign (−0 counts as positive).
fn fast_atan_quotient(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let invert = ay > ax;
    var r = atan_unit(select(ay, ax, invert) / select(ax, ay, invert));
    if (invert) {
        r = HALF_PI - r;
    }
    return select(r, -r, (x < 0.0) != (y < 0.0));
}

// atan2(y, x) in (−π, π], with atan2(0, 0) = 0.
fn fast_atan2(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let hi = max(ax, ay);
    let lo = min(ax, ay);
    var a = 0.0;
    if (hi > 0.0) {
        a = lo / hi;
    }
    var r = atan_unit(a);
    if (ay > ax) {
        r = HALF_PI - r;
    }
    if (x < 0.0) {
        r = PI - r;
    }
    return select(r, -r, y < 0.0);
}
