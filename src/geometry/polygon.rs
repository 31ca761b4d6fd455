//! Planar polygons in the image: whether corners trace a model's edges as a
//! simple polygon.

/// Two corners closer than this (pixels) are the same point.
const MIN_CORNER_SEPARATION_PX: f64 = 1e-6;
/// Two edges at a corner whose directions' sine is below this are on one line.
const MIN_CORNER_SINE: f64 = 1e-9;

/// Check that image `corners` (one per model vertex) trace the model's
/// polygon as a simple polygon: the two corners of an edge apart,
/// the two edges at a corner not on one line, and edges that share no
/// corner not touching (a bow-tie). `Err` is the message, to be blamed on the
/// file the corners came from (`init.json`). A model that is not a polygon (a corner on other than two
/// edges, an index out of range) passes: the tracker blames the model.
pub fn check_simple_polygon(corners: &[[f64; 2]], edges: &[[usize; 2]]) -> std::result::Result<(), String> {
    let n = corners.len();
    if n < 3 || edges.iter().flatten().any(|&i| i >= n) {
        return Ok(());
    }
    let mut degree = vec![0usize; n];
    for &i in edges.iter().flatten() {
        degree[i] += 1;
    }
    if degree.iter().any(|&d| d != 2) {
        return Ok(());
    }
    let sub = |a: [f64; 2], b: [f64; 2]| [a[0] - b[0], a[1] - b[1]];
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let norm = |a: [f64; 2]| a[0].hypot(a[1]);
    for (k, &[i, j]) in edges.iter().enumerate() {
        if norm(sub(corners[i], corners[j])) < MIN_CORNER_SEPARATION_PX {
            return Err(format!(
                "corners {i} and {j} (edge {k}) are both at {:?}: the corners must trace the model's polygon",
                corners[i]
            ));
        }
    }
    // Orientation of c relative to the line a→b: +1, −1, or 0 on the line.
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        let v = cross(sub(b, a), sub(c, a));
        let scale = norm(sub(b, a)) * norm(sub(c, a));
        if v.abs() <= MIN_CORNER_SINE * scale { 0 } else { v.signum() as i32 }
    };
    let within = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        c[0] >= a[0].min(b[0]) && c[0] <= a[0].max(b[0]) && c[1] >= a[1].min(b[1]) && c[1] <= a[1].max(b[1])
    };
    for (k, &[a, b]) in edges.iter().enumerate() {
        for (m, &[c, d]) in edges.iter().enumerate().skip(k + 1) {
            let (pa, pb, pc, pd) = (corners[a], corners[b], corners[c], corners[d]);
            let shared = [a, b].into_iter().find(|v| *v == c || *v == d);
            if let Some(v) = shared {
                let (u, w) = (if v == a { pb } else { pa }, if v == c { pd } else { pc });
                let (du, dw) = (sub(u, corners[v]), sub(w, corners[v]));
                if cross(du, dw).abs() <= MIN_CORNER_SINE * norm(du) * norm(dw) {
                    return Err(format!(
                        "edges {k} and {m} are on one line at corner {v}: the corners must trace the model's polygon"
                    ));
                }
                continue;
            }
            let (o1, o2, o3, o4) = (orient(pa, pb, pc), orient(pa, pb, pd), orient(pc, pd, pa), orient(pc, pd, pb));
            let crossing = (o1 * o2 < 0 && o3 * o4 < 0)
                || (o1 == 0 && within(pa, pb, pc))
                || (o2 == 0 && within(pa, pb, pd))
                || (o3 == 0 && within(pc, pd, pa))
                || (o4 == 0 && within(pc, pd, pb));
            if crossing {
                return Err(format!(
                    "edges {k} [{a}, {b}] and {m} [{c}, {d}] cross: the corners must trace the model's polygon \
                     without crossing itself (check the corner order)"
                ));
            }
        }
    }
    Ok(())
}
