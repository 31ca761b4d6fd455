//! Wavefront `.obj` models converted to a [`Model`].
//!
//! Read: `v x y z` vertices (numbers after z, a weight or a colour, are
//! ignored), `f` faces of three or more vertex references, each `a`, `a/b`,
//! `a//c` or `a/b/c` with `a` the vertex (1-based, or negative: −1 is the
//! last vertex listed so far; texture and normal references are ignored),
//! and `l` polylines, whose segments become edges. Ignored: `vn`, `vt`,
//! `vp`, `p`, grouping and display statements (`o`, `g`, `s`, `mg`,
//! `usemtl`, `mtllib` and the like) and `#` comments. Free-form curves and
//! surfaces (`cstype`, `curv`, `surf`, ...) are not polyhedra: an error, as
//! is any other statement. Every error names the file and the line.
//!
//! The faces are kept as they are, counter-clockwise seen from outside as
//! OBJ has them (SPEC §4's order too). The edges are the sides of the faces
//! where the surface bends: a side bordered by one face only, a side whose
//! two faces' normals (Newell's) differ by more than
//! [`FLAT_EDGE_ANGLE_DEGREES`], and a side of three or more faces; so a
//! flat face split into triangles gives no edges along its diagonals.
//! Then the segments of `l` lines not already edges. Each edge is listed
//! once, in the order it first appears, in the direction its first face
//! runs it.
//!
//! A point listed twice is an error (as in `model.json`): meshes exported
//! with one vertex per face corner need their vertices merged first. So is
//! a face with the vertices of an earlier one (listed twice, or both sides
//! of a thin plate), whose sides would border two coplanar faces and be no
//! edges. The
//! hand-written reader keeps the line of every vertex, face and edge, so
//! that [`Model::validate`]'s problems name it too.

use std::collections::HashMap;
use std::path::Path;

use crate::io::formats::{Model, ModelPart, newell_normal};
use crate::io::json::{one_short_line, read_text};
use crate::{Error, Result};

/// Two faces sharing a side whose normals differ by at most this angle,
/// in degrees, are one flat surface, and the side is not an edge. Well
/// below any crease a tracker could see, well above the rounding of
/// coordinates printed with six digits.
pub const FLAT_EDGE_ANGLE_DEGREES: f64 = 0.5;

/// OBJ statements that describe free-form geometry, which a polyhedral
/// model cannot hold.
const FREE_FORM: [&str; 15] = [
    "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp", "end", "con",
    "ctech",
];

/// OBJ statements that carry nothing a model holds (normals, texture
/// coordinates, points, groups, materials, display settings).
const IGNORED: [&str; 17] = [
    "vn", "vt", "vp", "p", "o", "g", "s", "mg", "usemtl", "mtllib", "usemap", "maplib", "lod", "bevel", "c_interp",
    "d_interp", "stech",
];

/// Read and convert a `.obj` file.
pub fn read_obj(path: &Path) -> Result<Model> {
    parse_obj(&read_text(path)?, path)
}

/// Convert the text of a `.obj` file; `path` names it in errors and gives
/// the model its name (the file stem).
pub fn parse_obj(text: &str, path: &Path) -> Result<Model> {
    let fail = |(line, msg): (usize, String)| Error::input(path, one_short_line(&format!("line {line}: {msg}")));
    let parsed = parse(text).map_err(fail)?;
    let (edges, edge_lines) = edges(&parsed);
    let name = path.file_stem().map_or_else(|| "model".to_string(), |s| s.to_string_lossy().into_owned());
    let model = Model {
        name,
        units: "m".to_string(),
        vertices: parsed.vertices,
        edges,
        faces: parsed.faces,
        joints: Vec::new(),
    };
    let line_of = |part| match part {
        ModelPart::Vertex(i) => parsed.vertex_lines.get(i).copied(),
        ModelPart::Edge(e) => edge_lines.get(e).copied(),
        ModelPart::Face(f) => parsed.face_lines.get(f).copied(),
        ModelPart::Joint(_) | ModelPart::JointVertex(..) => None,
    };
    model.validate_at(path, |part| line_of(part).map(|line| (path.to_path_buf(), line)))?;
    Ok(model)
}

/// The statements of an OBJ file that make a model, with their lines.
struct Parsed {
    vertices: Vec<[f64; 3]>,
    vertex_lines: Vec<usize>,
    faces: Vec<Vec<usize>>,
    face_lines: Vec<usize>,
    /// Segments of `l` polylines, with their lines.
    segments: Vec<([usize; 2], usize)>,
}

fn parse(text: &str) -> std::result::Result<Parsed, (usize, String)> {
    let mut parsed = Parsed {
        vertices: Vec::new(),
        vertex_lines: Vec::new(),
        faces: Vec::new(),
        face_lines: Vec::new(),
        segments: Vec::new(),
    };
    // Positive references may point past the vertices read so far; they
    // are checked once all are read.
    let mut references: Vec<(usize, i64)> = Vec::new();
    // Each face's vertex set, with its line: a face listed twice would
    // make each of its sides border two coplanar faces, and no edge.
    let mut face_sets: HashMap<Vec<usize>, usize> = HashMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else { continue };
        let fail = |msg: String| Err((line, msg));
        match keyword {
            "v" => {
                let numbers: Vec<&str> = tokens.collect();
                if numbers.len() < 3 {
                    return fail(format!(
                        "vertex {}: expected x y z, found {} numbers",
                        parsed.vertices.len() + 1,
                        numbers.len()
                    ));
                }
                let mut xyz = [0.0; 3];
                for (k, t) in numbers.iter().enumerate() {
                    let value = t.parse::<f64>().ok().filter(|v| v.is_finite());
                    match (value, k) {
                        (Some(v), 0..3) => xyz[k] = v,
                        (Some(_), _) => {}
                        (None, _) => {
                            return fail(format!("vertex {}: {t:?} is not a finite number", parsed.vertices.len() + 1));
                        }
                    }
                }
                parsed.vertices.push(xyz);
                parsed.vertex_lines.push(line);
            }
            "f" | "l" => {
                let what = if keyword == "f" { "face" } else { "polyline" };
                let mut loop_ = Vec::new();
                for t in tokens {
                    let vertex = t.split('/').next().unwrap_or("");
                    let Ok(reference) = vertex.parse::<i64>() else {
                        return fail(format!("{what}: {t:?} is not a vertex reference (a, a/b, a//c or a/b/c)"));
                    };
                    let index = match reference {
                        0 => return fail(format!("{what}: vertex reference 0: OBJ counts vertices from 1")),
                        r if r > 0 => {
                            references.push((line, r));
                            (r - 1) as usize
                        }
                        r => match parsed.vertices.len().checked_sub(r.unsigned_abs() as usize) {
                            Some(index) => index,
                            None => {
                                return fail(format!(
                                    "{what}: vertex reference {r} goes back past the first vertex ({} listed so far)",
                                    parsed.vertices.len()
                                ));
                            }
                        },
                    };
                    loop_.push(index);
                }
                if keyword == "f" {
                    if loop_.len() < 3 {
                        return fail(format!("face has {} vertices: a face needs at least 3", loop_.len()));
                    }
                    if let Some(k) = (1..loop_.len()).find(|&k| loop_[..k].contains(&loop_[k])) {
                        return fail(format!("face lists vertex {} twice", loop_[k] + 1));
                    }
                    let mut set = loop_.clone();
                    set.sort_unstable();
                    if let Some(first) = face_sets.insert(set, line) {
                        return fail(format!(
                            "face has the vertices of the face of line {first}: a face listed twice, or both sides of one, has no edges"
                        ));
                    }
                    parsed.faces.push(loop_);
                    parsed.face_lines.push(line);
                } else {
                    if loop_.len() < 2 {
                        return fail(format!("polyline has {} vertices: a line needs at least 2", loop_.len()));
                    }
                    for pair in loop_.windows(2) {
                        if pair[0] == pair[1] {
                            return fail(format!("polyline joins vertex {} to itself", pair[0] + 1));
                        }
                        parsed.segments.push(([pair[0], pair[1]], line));
                    }
                }
            }
            k if IGNORED.contains(&k) => {}
            k if FREE_FORM.contains(&k) => {
                return fail(format!("{k:?}: free-form curves and surfaces are not polyhedra, which a model needs"));
            }
            k => return fail(format!("unknown statement {k:?}")),
        }
    }
    let n = parsed.vertices.len();
    if let Some(&(line, r)) = references.iter().find(|&&(_, r)| r as u64 > n as u64) {
        return Err((line, format!("vertex reference {r} but the file has {n} vertices")));
    }
    Ok(parsed)
}

/// The edges (module doc) and the line each was read from.
fn edges(parsed: &Parsed) -> (Vec<[usize; 2]>, Vec<usize>) {
    // Each unordered side, in order of first appearance, with its faces.
    let mut sides: Vec<([usize; 2], Vec<usize>)> = Vec::new();
    let mut side_index: HashMap<(usize, usize), usize> = HashMap::new();
    for (f, face) in parsed.faces.iter().enumerate() {
        for k in 0..face.len() {
            let (a, b) = (face[k], face[(k + 1) % face.len()]);
            let s = *side_index.entry((a.min(b), a.max(b))).or_insert_with(|| {
                sides.push(([a, b], Vec::new()));
                sides.len() - 1
            });
            sides[s].1.push(f);
        }
    }
    let normals: Vec<Option<[f64; 3]>> =
        parsed.faces.iter().map(|face| unit(newell_normal(&parsed.vertices, face))).collect();
    let cos_flat = FLAT_EDGE_ANGLE_DEGREES.to_radians().cos();
    let flat = |f: usize, g: usize| match (normals[f], normals[g]) {
        (Some(n), Some(m)) => n.iter().zip(&m).map(|(a, b)| a * b).sum::<f64>() >= cos_flat,
        _ => false,
    };
    let mut edges = Vec::new();
    let mut lines = Vec::new();
    let mut listed = std::collections::HashSet::new();
    for (side, faces) in &sides {
        if !matches!(faces.as_slice(), [f, g] if flat(*f, *g)) {
            listed.insert((side[0].min(side[1]), side[0].max(side[1])));
            edges.push(*side);
            lines.push(parsed.face_lines[faces[0]]);
        }
    }
    for &([a, b], line) in &parsed.segments {
        if listed.insert((a.min(b), a.max(b))) {
            edges.push([a, b]);
            lines.push(line);
        }
    }
    (edges, lines)
}

/// `v` scaled to unit length; `None` for a zero or non-finite vector.
fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let length = v.iter().map(|c| c * c).sum::<f64>().sqrt();
    (length > 0.0 && length.is_finite()).then(|| v.map(|c| c / length))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Model> {
        parse_obj(text, Path::new("dir/shape.obj"))
    }

    fn err(text: &str) -> String {
        match parse(text) {
            Err(Error::Input { path, message }) => {
                assert_eq!(path, Path::new("dir/shape.obj"));
                message
            }
            other => panic!("expected an input error, got {other:?}"),
        }
    }

    /// The unit cube's corners (vertex i has x, y, z from bits 0, 1, 2 of
    /// i, 1-based in the file) and its six sides, counter-clockwise seen
    /// from outside, each as two triangles.
    const CUBE_TRIANGLES: &str = "# unit cube
o cube
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
v 0 0 1
v 1 0 1
v 0 1 1
v 1 1 1
vn 0 0 -1
vt 0 0
g sides
s off
usemtl grey
f 1//1 3//1 4//1
f 1//1 4//1 2//1
f 5 6 8
f 5 8 7
f 1/1 2/1 6/1
f 1/1 6/1 5/1
f 3/1/1 7/1/1 8/1/1
f 3/1/1 8/1/1 4/1/1
f 1 5 7
f 1 7 3
f 2 4 8
f 2 8 6
";

    #[test]
    fn a_cube_of_twelve_triangles_has_its_twelve_edges_only() {
        let m = parse(CUBE_TRIANGLES).unwrap();
        assert_eq!(m.name, "shape");
        assert_eq!(m.vertices.len(), 8);
        assert_eq!(m.vertices[5], [1.0, 0.0, 1.0]);
        assert_eq!(m.faces.len(), 12);
        assert_eq!(m.faces[0], vec![0, 2, 3]);
        assert_eq!(m.edges.len(), 12, "{:?}", m.edges);
        // Every edge joins corners that differ in one coordinate: no face diagonal.
        for &[a, b] in &m.edges {
            assert_eq!((a ^ b).count_ones(), 1, "edge {a}-{b}");
        }
        // In order of first appearance, in the direction the first face runs it.
        assert_eq!(m.edges[0], [0, 2]);
        assert_eq!(m.edges[1], [2, 3]);
    }

    #[test]
    fn a_bent_quad_split_in_two_triangles_keeps_its_diagonal() {
        // The quad (0,0,0) (1,0,0) (1,1,0.2) (0,1,0): its two halves meet at 5.7°.
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0.2\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";
        let m = parse(text).unwrap();
        assert_eq!(m.edges, vec![[0, 1], [1, 2], [2, 0], [2, 3], [3, 0]]);
        // Flat, the diagonal goes.
        let m = parse(&text.replace("1 1 0.2", "1 1 0")).unwrap();
        assert_eq!(m.edges, vec![[0, 1], [1, 2], [2, 3], [3, 0]]);
        // Within FLAT_EDGE_ANGLE_DEGREES it is flat too: a rise of 0.005 is 0.29°.
        let m = parse(&text.replace("1 1 0.2", "1 1 0.005")).unwrap();
        assert_eq!(m.edges.len(), 4);
    }

    #[test]
    fn negative_references_count_back_from_the_last_vertex_read() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf -3 -2 -1\nv 0 1 0\nf 1 -2 -1\nl 4/1 2\n";
        let m = parse(text).unwrap();
        assert_eq!(m.faces, vec![vec![0, 1, 2], vec![0, 2, 3]]);
        // Three outer sides of each triangle; their shared side 0-2 is flat;
        // the polyline's segment 3-1 is an edge of its own.
        assert_eq!(m.edges, vec![[0, 1], [1, 2], [2, 3], [3, 0], [3, 1]]);
    }

    #[test]
    fn vertices_may_carry_a_weight_or_a_colour() {
        let m = parse("v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(m.vertices[1], [1.0, 0.0, 0.0]);
    }

    #[test]
    fn bad_statements_name_their_line() {
        let ok = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
        let cases = [
            (format!("{ok}f 1 2\n"), "line 4: face has 2 vertices: a face needs at least 3"),
            (format!("{ok}f 1 2 9\n"), "line 4: vertex reference 9 but the file has 3 vertices"),
            (format!("{ok}f 1 2 -4\n"), "line 4: face: vertex reference -4 goes back past the first vertex"),
            (format!("{ok}f 1 2 0\n"), "line 4: face: vertex reference 0"),
            (format!("{ok}f 1 2 2\n"), "line 4: face lists vertex 2 twice"),
            (format!("{ok}f 1 2 3\nf 2 3 1\n"), "line 5: face has the vertices of the face of line 4"),
            (format!("{ok}f 1 2 3\nf 3 2 1\n"), "line 5: face has the vertices of the face of line 4"),
            (format!("{ok}f 1 2 x/1\n"), "line 4: face: \"x/1\" is not a vertex reference"),
            (format!("{ok}l 1\n"), "line 4: polyline has 1 vertices"),
            ("v 0 0\n".to_string(), "line 1: vertex 1: expected x y z, found 2 numbers"),
            ("v 0 0 nan\n".to_string(), "line 1: vertex 1: \"nan\" is not a finite number"),
            (format!("{ok}cstype bspline\n"), "line 4: \"cstype\": free-form curves and surfaces"),
            (format!("{ok}vertex 1 2 3\n"), "line 4: unknown statement \"vertex\""),
            // Problems of the whole model name the line of the part at fault.
            (format!("{ok}v 1 0 0\nf 1 2 3\n"), "line 4: vertex 3 repeats vertex 1"),
            (format!("{ok}v 2 0 0\nf 1 2 4\n"), "line 5: face 0 encloses no area"),
        ];
        for (text, expected) in cases {
            let msg = err(&text);
            assert!(msg.starts_with(expected), "{text:?}: {msg}");
        }
        assert!(err(ok).contains("no edges"));
    }
}
