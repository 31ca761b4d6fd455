//! ViSP's `.cao` model format, for rigid polyhedral models, converted to a
//! [`Model`].
//!
//! The format (one record per line; `#` starts a comment; elements other
//! than points may end with `key=value` parameters such as `name="left
//! wing"`, which are ignored here):
//!
//! ```text
//! V1                      header (optional)
//! 8                       number of 3-D points, then one `x y z` line each
//! 0 0 0
//! ...
//! 2                       number of 3-D lines, then one `i j` line each (point indices)
//! 0 1
//! ...
//! 1                       number of faces from lines, then `n l1 .. ln` (line indices)
//! 4 0 1 2 3
//! 6                       number of faces from points, then `n p1 .. pn` (point indices)
//! 4 0 1 2 3
//! 0                       number of cylinders (may be absent)
//! 0                       number of circles (may be absent)
//! ```
//!
//! Faces are counter-clockwise seen from outside in both ViSP and pipetrack,
//! so their order is kept. Conversion: the model's edges are the 3-D lines
//! followed by the sides of the faces from points, each unordered pair once;
//! its faces are the faces from points followed by the faces from lines, each
//! rebuilt as the vertex loop its lines form (in the direction of the listed
//! lines). What a [`Model`] cannot hold is an error naming the file and the
//! line: cylinders, circles, `load(...)` includes, and faces from lines that
//! do not form one closed loop.

use std::collections::HashSet;
use std::path::Path;

use crate::io::formats::Model;
use crate::io::json::one_short_line;
use crate::{Error, Result};

/// Read and convert a `.cao` file.
pub fn read_cao(path: &Path) -> Result<Model> {
    parse_cao(&super::json::read_text(path)?, path)
}

/// Convert the text of a `.cao` file; `path` names it in errors and gives
/// the model its name (the file stem).
pub fn parse_cao(text: &str, path: &Path) -> Result<Model> {
    let fail = |(line, msg): Failure| Error::input(path, one_short_line(&format!("line {line}: {msg}")));
    let records = tokenize(text).map_err(fail)?;
    let name = path.file_stem().map_or_else(|| "model".to_string(), |s| s.to_string_lossy().into_owned());
    let model = Parser { records, next: 0 }.model(name).map_err(fail)?;
    model.validate(path)?;
    Ok(model)
}

/// A parse failure: 1-based line number and message.
type Failure = (usize, String);

/// One non-empty line: its number and its tokens (comments removed, quoted
/// strings kept whole).
struct Record {
    line: usize,
    tokens: Vec<String>,
}

fn tokenize(text: &str) -> std::result::Result<Vec<Record>, Failure> {
    let mut records = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let mut tokens = Vec::new();
        let mut current = String::new();
        let mut in_quotes = false;
        for c in raw.chars() {
            match c {
                '"' => {
                    in_quotes = !in_quotes;
                    current.push(c);
                }
                '#' if !in_quotes => break,
                c if c.is_whitespace() && !in_quotes => {
                    if !current.is_empty() {
                        tokens.push(std::mem::take(&mut current));
                    }
                }
                c => current.push(c),
            }
        }
        if in_quotes {
            return Err((line, "unterminated quoted string".to_string()));
        }
        if !current.is_empty() {
            tokens.push(current);
        }
        if tokens.iter().any(|t| t.starts_with("load(")) {
            return Err((
                line,
                "load(...) includes another .cao file; pipetrack reads one self-contained file \
                 (merge the parts into it)"
                    .to_string(),
            ));
        }
        if !tokens.is_empty() {
            records.push(Record { line, tokens });
        }
    }
    Ok(records)
}

struct Parser {
    records: Vec<Record>,
    next: usize,
}

impl Parser {
    fn last_line(&self) -> usize {
        self.records.last().map_or(1, |r| r.line)
    }

    /// The next record, or an error saying `what` was expected.
    fn record(&mut self, what: &str) -> std::result::Result<&Record, Failure> {
        let line = self.last_line();
        let r = self.records.get(self.next).ok_or_else(|| (line, format!("file ends where {what} was expected")))?;
        self.next += 1;
        Ok(r)
    }

    /// Room for `count` records: no more than the records left, whatever
    /// the file claims, so a huge count fails when the file ends rather
    /// than when the memory does.
    fn capacity(&self, count: usize) -> usize {
        count.min(self.records.len().saturating_sub(self.next))
    }

    /// A line holding only a count.
    fn count(&mut self, what: &str) -> std::result::Result<(usize, usize), Failure> {
        let r = self.record(&format!("the number of {what}"))?;
        match r.tokens.as_slice() {
            [n] => n
                .parse()
                .map(|n| (r.line, n))
                .map_err(|_| (r.line, format!("expected the number of {what}, found {n:?}"))),
            _ => Err((
                r.line,
                format!("expected the number of {what} alone on its line, found {:?}", r.tokens.join(" ")),
            )),
        }
    }

    /// A record of `k` numeric fields, optionally followed by `key=value`
    /// parameters.
    fn fields<'a>(r: &'a Record, k: usize, what: &str) -> std::result::Result<&'a [String], Failure> {
        let numeric = r.tokens.iter().take_while(|t| !t.contains('=')).count();
        if numeric != k {
            return Err((r.line, format!("{what}: expected {k} numbers, found {numeric}")));
        }
        if let Some(t) = r.tokens[k..].iter().find(|t| !t.contains('=')) {
            return Err((r.line, format!("{what}: unexpected {t:?} among its key=value parameters")));
        }
        Ok(&r.tokens[..k])
    }

    fn index(r: &Record, token: &str, limit: usize, what: &str, of: &str) -> std::result::Result<usize, Failure> {
        let i: usize = token.parse().map_err(|_| (r.line, format!("{what}: {token:?} is not an index")))?;
        if i >= limit {
            return Err((r.line, format!("{what}: {of} index {i} is out of range ({limit} {of}s defined)")));
        }
        Ok(i)
    }

    fn model(mut self, name: String) -> std::result::Result<Model, Failure> {
        if let Some(first) = self.records.first() {
            let t = &first.tokens[0];
            if t == "V1" && first.tokens.len() == 1 {
                self.next = 1;
            } else if t.starts_with('V') {
                return Err((first.line, format!("unsupported header {:?}: expected V1", first.tokens.join(" "))));
            }
        }

        let (_, n_points) = self.count("3-D points")?;
        let mut vertices = Vec::with_capacity(self.capacity(n_points));
        for p in 0..n_points {
            let r = self.record(&format!("3-D point {p}"))?;
            let what = format!("3-D point {p}");
            let f = Self::fields(r, 3, &what)?;
            let mut xyz = [0.0; 3];
            for (c, t) in xyz.iter_mut().zip(f) {
                *c = t
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| (r.line, format!("{what}: {t:?} is not a finite number")))?;
            }
            vertices.push(xyz);
        }

        let mut edges = Vec::new();
        let mut seen = HashSet::new();
        let mut add_edge = |a: usize, b: usize| {
            if seen.insert((a.min(b), a.max(b))) {
                edges.push([a, b]);
            }
        };

        let (_, n_lines) = self.count("3-D lines")?;
        let mut lines = Vec::with_capacity(self.capacity(n_lines));
        for l in 0..n_lines {
            let what = format!("3-D line {l}");
            let r = self.record(&what)?;
            let f = Self::fields(r, 2, &what)?;
            let a = Self::index(r, &f[0], n_points, &what, "point")?;
            let b = Self::index(r, &f[1], n_points, &what, "point")?;
            if a == b {
                return Err((r.line, format!("{what} joins point {a} to itself")));
            }
            lines.push([a, b]);
            add_edge(a, b);
        }

        let (_, n_line_faces) = self.count("faces from lines")?;
        let mut line_faces = Vec::with_capacity(self.capacity(n_line_faces));
        for f in 0..n_line_faces {
            let what = format!("face from lines {f}");
            let r = self.record(&what)?;
            let ids = Self::polygon(r, n_lines, &what, "line")?;
            let face_lines: Vec<[usize; 2]> = ids.iter().map(|&i| lines[i]).collect();
            let face = close_loop(&face_lines).ok_or_else(|| {
                (r.line, format!("{what}: its lines do not form one closed loop, which a model face needs"))
            })?;
            line_faces.push(face);
        }

        let (_, n_point_faces) = self.count("faces from points")?;
        let mut faces = Vec::with_capacity(self.capacity(n_point_faces).saturating_add(line_faces.len()));
        for f in 0..n_point_faces {
            let what = format!("face from points {f}");
            let r = self.record(&what)?;
            let face = Self::polygon(r, n_points, &what, "point")?;
            for k in 0..face.len() {
                add_edge(face[k], face[(k + 1) % face.len()]);
            }
            faces.push(face);
        }
        faces.extend(line_faces);

        for what in ["cylinders", "circles"] {
            if self.next == self.records.len() {
                break; // older files end after the faces
            }
            let (line, n) = self.count(&format!("3-D {what}"))?;
            if n > 0 {
                return Err((
                    line,
                    format!("{n} {what}: a pipetrack model holds only polyhedra (points, lines, faces)"),
                ));
            }
        }
        if let Some(r) = self.records.get(self.next) {
            return Err((r.line, format!("unexpected {:?} after the last section (circles)", r.tokens.join(" "))));
        }
        Ok(Model { name, units: "m".to_string(), vertices, edges, faces, joints: Vec::new() })
    }

    /// `n i1 .. in`: a polygon of `n >= 3` distinct indices below `limit`.
    fn polygon(r: &Record, limit: usize, what: &str, of: &str) -> std::result::Result<Vec<usize>, Failure> {
        let n: usize =
            r.tokens[0].parse().map_err(|_| (r.line, format!("{what}: {:?} is not a count", r.tokens[0])))?;
        if n < 3 {
            return Err((r.line, format!("{what} has {n} {of}s: a face needs at least 3")));
        }
        let f = Self::fields(r, n.saturating_add(1), what)?;
        let mut ids = Vec::with_capacity(n);
        for t in &f[1..] {
            let i = Self::index(r, t, limit, what, of)?;
            if ids.contains(&i) {
                return Err((r.line, format!("{what} lists {of} {i} twice")));
            }
            ids.push(i);
        }
        Ok(ids)
    }
}

/// The vertex loop formed by `lines` (point-index pairs), following the
/// direction of the first line as the second one continues it; `None`
/// unless they form exactly one closed loop.
fn close_loop(lines: &[[usize; 2]]) -> Option<Vec<usize>> {
    let [a, b] = *lines.first()?;
    // Each vertex of a single closed loop ends exactly two of its lines.
    let mut degree = std::collections::HashMap::new();
    for &[p, q] in lines {
        *degree.entry(p).or_insert(0) += 1;
        *degree.entry(q).or_insert(0) += 1;
    }
    if degree.values().any(|&d| d != 2) {
        return None;
    }
    let second = lines.get(1)?;
    let (start, mut current) = if second.contains(&b) { (a, b) } else { (b, a) };
    let mut used = vec![false; lines.len()];
    used[0] = true;
    let mut face = vec![start, current];
    for _ in 1..lines.len() {
        let k = (0..lines.len()).find(|&k| !used[k] && lines[k].contains(&current))?;
        used[k] = true;
        current = if lines[k][0] == current { lines[k][1] } else { lines[k][0] };
        face.push(current);
    }
    // Back at the start, having used every line: one loop.
    (face.pop() == Some(start) && used.iter().all(|&u| u)).then_some(face)
}

#[cfg(test)]
mod tests {
    use super::*;

    const CUBE: &str = "V1
# A unit cube: faces from points, plus one redundant 3-D line.
8                 # Number of points
0 0 0             # 0
0 0 1
0 1 1
0 1 0
1 0 0
1 0 1
1 1 1
1 1 0             # 7
# 3D lines
1
0 1   name=\"front # edge\"
# Faces from 3D lines
0
# Faces from 3D points
6
4 0 1 2 3   name=left
4 4 7 6 5
4 0 4 5 1
4 3 2 6 7
4 0 3 7 4
4 1 5 6 2
# 3D cylinders
0
# 3D circles
0
";

    fn parse(text: &str) -> Result<Model> {
        parse_cao(text, Path::new("dir/cube.cao"))
    }

    fn err(text: &str) -> String {
        match parse(text) {
            Err(Error::Input { path, message }) => {
                assert_eq!(path, Path::new("dir/cube.cao"));
                message
            }
            other => panic!("expected an input error, got {other:?}"),
        }
    }

    #[test]
    fn cube_from_points() {
        let m = parse(CUBE).unwrap();
        assert_eq!(m.name, "cube");
        assert_eq!(m.vertices.len(), 8);
        assert_eq!(m.vertices[6], [1.0, 1.0, 1.0]);
        assert_eq!(m.faces.len(), 6);
        assert_eq!(m.faces[1], vec![4, 7, 6, 5]);
        // 12 cube edges; the 3-D line 0-1 comes first and is not repeated.
        assert_eq!(m.edges.len(), 12);
        assert_eq!(m.edges[0], [0, 1]);
        let pairs: HashSet<_> = m.edges.iter().map(|&[a, b]| (a.min(b), a.max(b))).collect();
        assert_eq!(pairs.len(), 12);
        assert!(pairs.contains(&(2, 6)) && !pairs.contains(&(0, 6)));
    }

    /// The same square face given as lines in mixed directions.
    const SQUARE_FROM_LINES: &str = "V1
4
0 0 0
1 0 0
1 1 0
0 1 0
4
1 0
1 2
3 2
0 3
1
4 0 1 2 3
0
";

    #[test]
    fn face_from_lines_becomes_a_vertex_loop() {
        let m = parse(SQUARE_FROM_LINES).unwrap();
        // Line 0 is (1,0) but line 1 continues from 1, so the loop runs 0,1,2,3.
        assert_eq!(m.faces, vec![vec![0, 1, 2, 3]]);
        assert_eq!(m.edges, vec![[1, 0], [1, 2], [3, 2], [0, 3]]);
    }

    #[test]
    fn close_loop_follows_the_listed_direction() {
        assert_eq!(close_loop(&[[0, 1], [1, 2], [2, 0]]), Some(vec![0, 1, 2]));
        assert_eq!(close_loop(&[[1, 0], [2, 1], [0, 2]]), Some(vec![0, 1, 2]));
        assert_eq!(close_loop(&[[0, 1], [0, 2], [2, 1]]), Some(vec![1, 0, 2]));
        // Open chain, and two separate triangles.
        assert_eq!(close_loop(&[[0, 1], [1, 2], [2, 3]]), None);
        assert_eq!(close_loop(&[[0, 1], [1, 2], [2, 0], [3, 4], [4, 5], [5, 3]]), None);
    }

    #[test]
    fn open_face_from_lines_is_an_error() {
        let text = SQUARE_FROM_LINES.replace("4\n1 0\n1 2\n3 2\n0 3\n1\n4 0 1 2 3", "3\n0 1\n1 2\n2 3\n1\n3 0 1 2");
        let msg = err(&text);
        assert!(msg.starts_with("line 12: face from lines 0") && msg.contains("closed loop"), "{msg}");
    }

    #[test]
    fn cylinders_circles_and_includes_are_refused() {
        let msg = err(&CUBE.replace("# 3D cylinders\n0", "# 3D cylinders\n1\n0 1 0.5"));
        assert!(msg.starts_with("line 26: 1 cylinders"), "{msg}");
        let msg = err(&CUBE.replace("# 3D circles\n0", "# 3D circles\n2"));
        assert!(msg.starts_with("line 28: 2 circles"), "{msg}");
        let msg = err(&CUBE.replace("V1\n", "V1\nload(\"wings.cao\")\n"));
        assert!(msg.starts_with("line 2: load(...)"), "{msg}");
    }

    #[test]
    fn cylinder_and_circle_sections_may_be_absent() {
        let cut = CUBE.find("# 3D cylinders").unwrap();
        assert_eq!(parse(&CUBE[..cut]).unwrap().faces.len(), 6);
    }

    #[test]
    fn malformed_records_name_their_line() {
        assert!(err(&CUBE.replace("0 1 1\n", "0 1\n")).starts_with("line 6: 3-D point 2: expected 3 numbers, found 2"));
        assert!(
            err(&CUBE.replace("1 1 0             # 7", "1 nan 0"))
                .starts_with("line 11: 3-D point 7: \"nan\" is not a finite number")
        );
        assert!(
            err(&CUBE.replace("4 4 7 6 5", "4 4 7 6 8"))
                .starts_with("line 20: face from points 1: point index 8 is out of range")
        );
        assert!(
            err(&CUBE.replace("4 4 7 6 5", "4 4 7 6 6")).starts_with("line 20: face from points 1 lists point 6 twice")
        );
        assert!(
            err(&CUBE.replace("4 4 7 6 5", "4 4 7 6"))
                .starts_with("line 20: face from points 1: expected 5 numbers, found 4")
        );
        assert!(
            err(&CUBE.replace("0 1   name", "0 0   name")).starts_with("line 14: 3-D line 0 joins point 0 to itself")
        );
        assert!(
            err(&CUBE.replace("8                 # Number", "eight # Number"))
                .starts_with("line 3: expected the number of 3-D points")
        );
        assert!(err("V2\n").contains("unsupported header"));
        assert!(err(&format!("{CUBE}7\n")).starts_with("line 29: unexpected \"7\""));
        assert!(
            err(&CUBE[..CUBE.find("# Faces from 3D points").unwrap()])
                .contains("file ends where the number of faces from points")
        );
    }

    #[test]
    fn header_is_optional() {
        assert_eq!(parse(&CUBE.replacen("V1\n", "", 1)).unwrap().vertices.len(), 8);
    }
}
