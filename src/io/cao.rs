//! ViSP's `.cao` model format, for rigid polyhedral models, converted to a
//! [`Model`], with ViSP's `load(...)` includes.
//!
//! The format (one record per line; a `#` starts a comment, outside quoted
//! strings; after the numbers a record needs, the rest of its line is
//! `key=value` parameters such as `name="left wing"` and free comment text
//! such as `// left wing`, both ignored here, as ViSP ignores all but a few
//! parameters; a further number there is an error, a miscounted record):
//!
//! ```text
//! V1                      header: V1 (or V0), or V2 whose points carry two more numbers
//! load("part.cao")        includes, if any (below)
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
//! line: cylinders and circles (a count of zero is fine), and faces from
//! lines that do not form one closed loop. The header is optional here
//! (ViSP requires it).
//!
//! **Includes**, as ViSP's `vpMbTracker::loadCAOModel` reads them:
//!
//! - `load("path")` lines stand right after the header, before the number of
//!   points, one per line; a `load(` anywhere else is an error. The path is
//!   relative to the folder of the file that holds the line (or absolute).
//! - `load("path", t=[x; y; z], tu=[a; b; c])` places the included part:
//!   each of its points X becomes R·X + t (each value of t within the
//!   model coordinates' bound, ±[`MAX_MODEL_COORDINATE`]), with R the
//!   rotation by the theta-u (axis-angle) vector `tu`, in radians, or in
//!   degrees where a value ends in `deg` (`rad` is allowed too);
//!   `R=[r11; r12; ...; r33]` gives R row by row instead of `tu`. An
//!   included file may include others: the placements compose, the outer
//!   one applied last.
//! - Each file's point, line and face indices are its own (they count from
//!   0 in every file); the merged model lists the parts in the order ViSP
//!   reads them, depth first: a file's includes, in order, then its own
//!   points, so its indices are offset by the number of vertices before it.
//!   This is the model-vertex order of `init.json`'s corners.
//! - A file of only a header and includes is a whole model (a file with
//!   neither includes nor points is an error).
//! - Points of different parts that coincide (within
//!   [`DUPLICATE_VERTEX_TOLERANCE`] of the model's size), as where two parts
//!   touch, become one vertex, and an edge the parts share is kept once;
//!   within one file a point listed twice stays an error.
//! - A file that includes itself, directly or through others, is an error
//!   (ViSP warns and skips the include) naming the including file, its line
//!   and the chain of files; so is the `load` of a missing file. A file
//!   included twice (not in a cycle) is read twice, as ViSP does: give the
//!   copies different placements. At most [`MAX_FILES_READ`] readings make
//!   one model, and includes nest at most [`MAX_LOAD_DEPTH`] files deep.
//!
//! Errors name the file they are in (an included file's own errors name
//! it) and the line; problems of the merged model found by
//! [`Model::validate`] name the file and line of the part at fault.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};

use crate::Result;
use crate::bounds::short_number;
use crate::io::formats::{
    DUPLICATE_VERTEX_TOLERANCE, MAX_MODEL_COORDINATE, Model, ModelPart, PointGrid, bounding_diagonal,
};
use crate::io::json::{input_error, read_text};

/// Read and convert a `.cao` file and the files it includes.
pub fn read_cao(path: &Path) -> Result<Model> {
    parse_cao(&read_text(path)?, path)
}

/// Convert the text of the `.cao` file at `path`; `path` names it in
/// errors, gives the model its name (the file stem) and the folder that
/// the paths of its `load(...)` lines are relative to.
pub fn parse_cao(text: &str, path: &Path) -> Result<Model> {
    let mut merged = Merged::default();
    let mut reading = Vec::new();
    read_part(text, path, &Placement::IDENTITY, &mut reading, &mut merged)?;
    let name = path.file_stem().map_or_else(|| "model".to_string(), |s| s.to_string_lossy().into_owned());
    merged.into_model(name, path)
}

/// A parse failure: 1-based line number and message.
type Failure = (usize, String);

/// Where a part of the merged model was written: the index of the file (in
/// [`Merged::files`]) and the 1-based line.
type Origin = (usize, usize);

/// The rigid placement of an included part: X ↦ R·X + t.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Placement {
    rotation: DMat3,
    translation: DVec3,
}

impl Placement {
    const IDENTITY: Self = Self { rotation: DMat3::IDENTITY, translation: DVec3::ZERO };

    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        if *self == Self::IDENTITY {
            return p;
        }
        (self.rotation * DVec3::from_array(p) + self.translation).to_array()
    }

    /// `inner` followed by `self`: the placement of a part placed by
    /// `inner` within a part placed by `self`.
    fn after(&self, inner: &Placement) -> Placement {
        Placement {
            rotation: self.rotation * inner.rotation,
            translation: self.rotation * inner.translation + self.translation,
        }
    }
}

/// The parts read so far, merged, with where each element was written.
#[derive(Default)]
struct Merged {
    /// Every file read, once per time it was read.
    files: Vec<PathBuf>,
    vertices: Vec<[f64; 3]>,
    vertex_origins: Vec<Origin>,
    edges: Vec<[usize; 2]>,
    edge_origins: Vec<Origin>,
    faces: Vec<Vec<usize>>,
    face_origins: Vec<Origin>,
}

impl Merged {
    /// The model: coincident points of different parts made one, edges
    /// listed once, then checked by [`Model::validate`], whose errors name
    /// the file and line of the part at fault.
    fn into_model(mut self, name: String, path: &Path) -> Result<Model> {
        if self.files.len() > 1 {
            self.join_coincident_points();
        }
        let mut seen = HashSet::with_capacity(self.edges.len());
        let mut edges = Vec::with_capacity(self.edges.len());
        let mut edge_origins = Vec::with_capacity(self.edges.len());
        for (&[a, b], &origin) in self.edges.iter().zip(&self.edge_origins) {
            if seen.insert((a.min(b), a.max(b))) {
                edges.push([a, b]);
                edge_origins.push(origin);
            }
        }
        let model = Model {
            name,
            units: "m".to_string(),
            vertices: self.vertices,
            edges,
            faces: self.faces,
            joints: Vec::new(),
        };
        let files = &self.files;
        let named = |(file, line): Origin| Some((files[file].clone(), line));
        model.validate_at(path, |part| match part {
            ModelPart::Vertex(i) => self.vertex_origins.get(i).copied().and_then(named),
            ModelPart::Edge(e) => edge_origins.get(e).copied().and_then(named),
            ModelPart::Face(f) => self.face_origins.get(f).copied().and_then(named),
            ModelPart::Joint(_) | ModelPart::JointVertex(..) => None,
        })?;
        Ok(model)
    }

    /// Make each point that coincides with a point of an earlier part
    /// (another file, or another reading of one) that point.
    fn join_coincident_points(&mut self) {
        let part = |i: usize| self.vertex_origins[i].0;
        let size = bounding_diagonal(&self.vertices);
        let mut grid = PointGrid::new(&self.vertices, DUPLICATE_VERTEX_TOLERANCE * size);
        let mut new_index = Vec::with_capacity(self.vertices.len());
        let mut kept = Vec::with_capacity(self.vertices.len());
        for j in 0..self.vertices.len() {
            match grid.earliest_near(j) {
                Some(i) if part(i) != part(j) => new_index.push(new_index[i]),
                _ => {
                    grid.insert(j);
                    new_index.push(kept.len());
                    kept.push(j);
                }
            }
        }
        if kept.len() == self.vertices.len() {
            return;
        }
        self.vertices = kept.iter().map(|&j| self.vertices[j]).collect();
        self.vertex_origins = kept.iter().map(|&j| self.vertex_origins[j]).collect();
        for edge in &mut self.edges {
            *edge = edge.map(|v| new_index[v]);
        }
        for face in &mut self.faces {
            for v in face.iter_mut() {
                *v = new_index[*v];
            }
        }
    }
}

/// Read one file into `merged`: its includes first (each placed by
/// `placement` after its own), then its own elements. `reading` holds the
/// files being read, outermost first, to find cycles.
fn read_part(
    text: &str,
    path: &Path,
    placement: &Placement,
    reading: &mut Vec<PathBuf>,
    merged: &mut Merged,
) -> Result<()> {
    let fail = |(line, msg): Failure| input_error(path, format!("line {line}: {msg}"));
    let records = tokenize(text).map_err(fail)?;
    let mut parser = Parser { records, next: 0, point_fields: 3 };
    parser.header().map_err(fail)?;
    let includes = parser.includes().map_err(fail)?;

    reading.push(std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()));
    for include in &includes {
        let included = match Path::new(&include.path) {
            p if p.is_absolute() => p.to_path_buf(),
            p => path.parent().unwrap_or(Path::new("")).join(p),
        };
        let fail = |msg: String| input_error(path, format!("line {}: {msg}", include.line));
        if included.is_dir() {
            return Err(fail(format!("load(\"{}\"): is a folder, not a .cao file", include.path)));
        }
        if !included.is_file() {
            return Err(fail(format!(
                "load(\"{}\"): no such file (a path is relative to the folder of the file that loads it)",
                include.path
            )));
        }
        let canonical = std::fs::canonicalize(&included).unwrap_or_else(|_| included.clone());
        if let Some(start) = reading.iter().position(|p| *p == canonical) {
            let chain: Vec<String> = reading[start..]
                .iter()
                .chain(std::iter::once(&canonical))
                .map(|p| p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned()))
                .collect();
            return Err(fail(format!(
                "load(\"{}\") makes a cycle of includes ({}): a file may not include itself",
                include.path,
                chain.join(" → ")
            )));
        }
        if reading.len() + 1 > MAX_LOAD_DEPTH {
            return Err(fail(format!(
                "load(\"{}\"): includes nested more than {MAX_LOAD_DEPTH} files deep",
                include.path
            )));
        }
        if merged.files.len() + reading.len() >= MAX_FILES_READ {
            return Err(fail(format!(
                "load(\"{}\"): more than {MAX_FILES_READ} files read for one model: are files included many times over?",
                include.path
            )));
        }
        let text = read_text(&included)?;
        read_part(&text, &included, &placement.after(&include.placement), reading, merged)?;
    }
    reading.pop();

    let file = merged.files.len();
    merged.files.push(path.to_path_buf());
    parser.body(!includes.is_empty(), placement, file, merged).map_err(fail)
}

/// The most file readings one model may take (a file included twice
/// counts twice), so that files including each other many times over
/// fail rather than run for ever.
pub const MAX_FILES_READ: usize = 10_000;

/// The deepest chain of includes one model may have (a file that loads a
/// file that loads a file… counts each), so that a chain of thousands of
/// files fails with an error rather than exhausting the stack.
pub const MAX_LOAD_DEPTH: usize = 64;

/// One `load(...)` line.
struct Include {
    line: usize,
    path: String,
    placement: Placement,
}

/// One non-empty line: its number, its text without the comment, and its
/// tokens (quoted strings kept whole).
struct Record {
    line: usize,
    text: String,
    tokens: Vec<String>,
}

fn tokenize(text: &str) -> std::result::Result<Vec<Record>, Failure> {
    let mut records = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let mut tokens = Vec::new();
        let mut current = String::new();
        let mut in_quotes = false;
        let mut end = raw.len();
        for (at, c) in raw.char_indices() {
            match c {
                '"' => {
                    in_quotes = !in_quotes;
                    current.push(c);
                }
                '#' if !in_quotes => {
                    end = at;
                    break;
                }
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
        if !tokens.is_empty() {
            records.push(Record { line, text: raw[..end].trim().to_string(), tokens });
        }
    }
    Ok(records)
}

/// Whether a record is a `load(...)` line.
fn is_load(r: &Record) -> bool {
    r.text.starts_with("load")
}

/// Parse the text of a `load(...)` line:
/// `load("path"[, t=[x; y; z]][, tu=[a; b; c] | R=[r11; ...; r33]])`, then
/// free text.
fn parse_load(text: &str) -> std::result::Result<(String, Placement), String> {
    let usage = "expected load(\"file.cao\") with optional t=[x; y; z] and tu=[a; b; c] or R=[9 values]";
    let rest = text.strip_prefix("load(").ok_or_else(|| usage.to_string())?.trim_start();
    let rest =
        rest.strip_prefix('"').ok_or_else(|| format!("load(...): the path must be in double quotes: {usage}"))?;
    let close_quote = rest.find('"').ok_or_else(|| usage.to_string())?;
    let path = rest[..close_quote].to_string();
    if path.is_empty() {
        return Err("load(\"\"): the path is empty".to_string());
    }
    let rest = &rest[close_quote + 1..];
    let close = rest.find(')').ok_or_else(|| format!("load(\"{path}\": no closing parenthesis"))?;
    let mut translation = DVec3::ZERO;
    let mut rotation: Option<(&str, DMat3)> = None;
    for param in rest[..close].split(',').map(str::trim).skip(1) {
        let (key, values) = param
            .split_once('=')
            .and_then(|(k, v)| Some((k.trim(), v.trim().strip_prefix('[')?.strip_suffix(']')?)))
            .ok_or_else(|| format!("load(\"{path}\"): {param:?} is not key=[values]: {usage}"))?;
        let values: Vec<&str> = values.split(';').map(str::trim).collect();
        let numbers = |n: usize, angles: bool| -> std::result::Result<Vec<f64>, String> {
            if values.len() != n {
                return Err(format!(
                    "load(\"{path}\"): {key}= needs {n} values separated by ';', found {}",
                    values.len()
                ));
            }
            values
                .iter()
                .map(|v| {
                    let (number, scale) = match (v.strip_suffix("deg"), v.strip_suffix("rad")) {
                        (Some(n), _) if angles => (n.trim(), std::f64::consts::PI / 180.0),
                        (_, Some(n)) if angles => (n.trim(), 1.0),
                        _ => (*v, 1.0),
                    };
                    number
                        .parse::<f64>()
                        .ok()
                        .map(|x| x * scale)
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| format!("load(\"{path}\"): {key}=: {v:?} is not a finite number"))
                })
                .collect()
        };
        match key {
            "t" => {
                let t = numbers(3, false)?;
                if let Some(v) = t.iter().find(|v| v.abs() > MAX_MODEL_COORDINATE) {
                    return Err(format!(
                        "load(\"{path}\"): t=: {} is beyond ±{}, the bound of a model's coordinates",
                        short_number(*v),
                        short_number(MAX_MODEL_COORDINATE)
                    ));
                }
                translation = DVec3::from_slice(&t);
            }
            "tu" | "R" if rotation.is_some() => {
                return Err(format!("load(\"{path}\"): give one rotation, tu= or R=, once"));
            }
            "tu" => {
                let tu = DVec3::from_slice(&numbers(3, true)?);
                let angle = tu.length();
                let r = if angle > 0.0 { DMat3::from_axis_angle(tu / angle, angle) } else { DMat3::IDENTITY };
                rotation = Some(("tu", r));
            }
            "R" => {
                let rows = numbers(9, false)?;
                let r = DMat3::from_cols_slice(&rows).transpose();
                let off_orthonormal =
                    (r.transpose() * r - DMat3::IDENTITY).to_cols_array().iter().fold(0.0f64, |m, x| m.max(x.abs()));
                if !(off_orthonormal < ROTATION_TOLERANCE && r.determinant() > 0.0) {
                    return Err(format!(
                        "load(\"{path}\"): R= is not a rotation matrix (rows of unit length, at right angles, determinant 1)"
                    ));
                }
                rotation = Some(("R", r));
            }
            _ => return Err(format!("load(\"{path}\"): unknown parameter {key:?}: {usage}")),
        }
    }
    let rotation = rotation.map_or(DMat3::IDENTITY, |(_, r)| r);
    Ok((path, Placement { rotation, translation }))
}

/// How far RᵀR may be from the identity (largest entry) for `R=[...]` to
/// be taken as a rotation: values printed with six or more digits pass.
const ROTATION_TOLERANCE: f64 = 1e-5;

struct Parser {
    records: Vec<Record>,
    next: usize,
    /// Numbers on a point's line: 3, or 5 in a `V2` file.
    point_fields: usize,
}

impl Parser {
    fn last_line(&self) -> usize {
        self.records.last().map_or(1, |r| r.line)
    }

    /// The next record, or an error saying `what` was expected; a
    /// `load(...)` line here is out of place.
    fn record(&mut self, what: &str) -> std::result::Result<&Record, Failure> {
        let line = self.last_line();
        let r = self.records.get(self.next).ok_or_else(|| (line, format!("file ends where {what} was expected")))?;
        if is_load(r) {
            return Err((
                r.line,
                "load(...) may stand only right after the V1 header, before the number of points".to_string(),
            ));
        }
        self.next += 1;
        Ok(r)
    }

    /// Room for `count` records: no more than the records left, whatever
    /// the file claims, so a huge count fails when the file ends rather
    /// than when the memory does.
    fn capacity(&self, count: usize) -> usize {
        count.min(self.records.len().saturating_sub(self.next))
    }

    /// The optional header: `V0` or `V1`, or `V2` (points with two image
    /// coordinates after x y z).
    fn header(&mut self) -> std::result::Result<(), Failure> {
        let Some(first) = self.records.first() else { return Ok(()) };
        let t = first.tokens[0].as_str();
        if !t.starts_with('V') {
            return Ok(());
        }
        self.point_fields = match t {
            "V0" | "V1" => 3,
            "V2" => 5,
            _ => return Err((first.line, format!("unsupported header {t:?}: expected V1 (or V0, V2)"))),
        };
        self.next = 1;
        Ok(())
    }

    /// The `load(...)` lines right after the header.
    fn includes(&mut self) -> std::result::Result<Vec<Include>, Failure> {
        let mut includes = Vec::new();
        while let Some(r) = self.records.get(self.next).filter(|r| is_load(r)) {
            let (path, placement) = parse_load(&r.text).map_err(|msg| (r.line, msg))?;
            includes.push(Include { line: r.line, path, placement });
            self.next += 1;
        }
        Ok(includes)
    }

    /// A line holding a count, then perhaps a comment.
    fn count(&mut self, what: &str) -> std::result::Result<(usize, usize), Failure> {
        let r = self.record(&format!("the number of {what}"))?;
        let n = &r.tokens[0];
        if r.tokens.get(1).is_some_and(|t| t.parse::<f64>().is_ok()) {
            return Err((
                r.line,
                format!("expected the number of {what} alone on its line, found {:?}", r.tokens.join(" ")),
            ));
        }
        n.parse().map(|n| (r.line, n)).map_err(|_| (r.line, format!("expected the number of {what}, found {n:?}")))
    }

    /// The first `k` tokens of a record, its numeric fields; after them
    /// come `key=value` parameters and comment text, ignored, but not a
    /// further number (the record would not be what its count says).
    fn fields<'a>(r: &'a Record, k: usize, what: &str) -> std::result::Result<&'a [String], Failure> {
        let before_parameters = r.tokens.iter().take_while(|t| !t.contains('=')).count();
        if before_parameters < k {
            return Err((r.line, format!("{what}: expected {k} numbers, found {before_parameters}")));
        }
        let extra = r.tokens[k..].iter().take_while(|t| t.parse::<f64>().is_ok()).count();
        if extra > 0 {
            return Err((r.line, format!("{what}: expected {k} numbers, found {}", k + extra)));
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

    /// The file's own points, lines and faces, after its includes, into
    /// `merged` (points placed by `placement`, indices offset by the
    /// vertices already there), as the `file`-th file read.
    fn body(
        mut self,
        has_includes: bool,
        placement: &Placement,
        file: usize,
        merged: &mut Merged,
    ) -> std::result::Result<(), Failure> {
        if has_includes && self.next == self.records.len() {
            return Ok(()); // a model made of its includes only
        }
        let offset = merged.vertices.len();
        let (count_line, n_points) = self.count("3-D points")?;
        if n_points == 0 && !has_includes {
            return Err((count_line, "0 3-D points: a file without load(...) includes needs points".to_string()));
        }
        merged.vertices.reserve(self.capacity(n_points));
        let point_fields = self.point_fields;
        for p in 0..n_points {
            let what = format!("3-D point {p}");
            let r = self.record(&what)?;
            let f = Self::fields(r, point_fields, &what)?;
            let mut xyz = [0.0; 3];
            for (c, t) in xyz.iter_mut().zip(f) {
                *c = t
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| (r.line, format!("{what}: {t:?} is not a finite number")))?;
            }
            if let Some(t) = f[3..].iter().find(|t| t.parse::<i64>().is_err()) {
                return Err((r.line, format!("{what}: image coordinate {t:?} is not an integer")));
            }
            let line = r.line;
            merged.vertices.push(placement.apply(xyz));
            merged.vertex_origins.push((file, line));
        }

        let mut seen = HashSet::new();
        let mut add_edge = |a: usize, b: usize, line: usize| {
            if seen.insert((a.min(b), a.max(b))) {
                merged.edges.push([offset + a, offset + b]);
                merged.edge_origins.push((file, line));
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
            add_edge(a, b, r.line);
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
            line_faces.push((face, r.line));
        }

        let (_, n_point_faces) = self.count("faces from points")?;
        let mut faces = Vec::with_capacity(self.capacity(n_point_faces).saturating_add(line_faces.len()));
        for f in 0..n_point_faces {
            let what = format!("face from points {f}");
            let r = self.record(&what)?;
            let face = Self::polygon(r, n_points, &what, "point")?;
            for k in 0..face.len() {
                add_edge(face[k], face[(k + 1) % face.len()], r.line);
            }
            faces.push((face, r.line));
        }
        faces.extend(line_faces);
        for (face, line) in faces {
            merged.faces.push(face.into_iter().map(|v| offset + v).collect());
            merged.face_origins.push((file, line));
        }

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
        Ok(())
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
    use crate::Error;

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
    fn cylinders_and_circles_are_refused() {
        let msg = err(&CUBE.replace("# 3D cylinders\n0", "# 3D cylinders\n1\n0 1 0.5"));
        assert!(msg.starts_with("line 26: 1 cylinders"), "{msg}");
        let msg = err(&CUBE.replace("# 3D circles\n0", "# 3D circles\n2"));
        assert!(msg.starts_with("line 28: 2 circles"), "{msg}");
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
        assert!(err("V3\n").contains("unsupported header"));
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

    #[test]
    fn trailing_comments_without_hash_and_v2_points_are_read() {
        // ViSP's own documentation ends records with `// comment`.
        let text = CUBE
            .replace("0 0 0             # 0", "0 0 0  // point 0")
            .replace("4 0 1 2 3   name=left", "4 0 1 2 3 // left");
        assert_eq!(parse(&text).unwrap(), parse(CUBE).unwrap());
        let msg = err(&CUBE.replace("0 0 0             # 0", "0 0 0 1"));
        assert!(msg.starts_with("line 4: 3-D point 0: expected 3 numbers, found 4"), "{msg}");
        // V2: two image coordinates after each point.
        let mut v2 = String::from("V2\n");
        for (k, line) in CUBE.lines().enumerate().skip(1) {
            v2.push_str(line);
            v2.push_str(if (3..11).contains(&k) { " 10 20\n" } else { "\n" });
        }
        let v2 = v2.replace("# 0 10 20", "10 20 # 0").replace("# 7 10 20", "10 20 # 7");
        assert_eq!(parse(&v2).unwrap(), parse(CUBE).unwrap());
        assert!(err(&v2.replace("0 1 0 10 20", "0 1 0 10 x")).contains("image coordinate \"x\" is not an integer"));
    }

    #[test]
    fn a_point_listed_twice_names_its_line() {
        let msg = err(&CUBE.replace("1 1 0             # 7", "1 1 1"));
        assert!(msg.starts_with("line 11: vertex 7 repeats vertex 6"), "{msg}");
    }

    /// A fresh folder under the temp folder holding `files` (relative path,
    /// text), removed when dropped.
    fn folder(name: &str, files: &[(&str, &str)]) -> tempfile::TempDir {
        let dir = tempfile::Builder::new().prefix(&format!("pipetrack-cao-{name}-")).tempdir().unwrap();
        for (path, text) in files {
            let path = dir.path().join(path);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        }
        dir
    }

    /// The input error of reading `path`: the file it names and its message.
    fn read_err(path: &Path) -> (PathBuf, String) {
        match read_cao(path) {
            Err(Error::Input { path, message }) => (path, message),
            other => panic!("expected an input error, got {other:?}"),
        }
    }

    /// A unit square in z = 0 (points 0..3), its four sides as 3-D lines, no faces.
    const SQUARE: &str = "V1\n4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4\n0 1\n1 2\n2 3\n3 0\n0\n0\n0\n0\n";

    #[test]
    fn includes_merge_two_levels_with_offset_indices() {
        // top.cao ⊃ parts/mid.cao ⊃ parts/leaf.cao; each file's own indices count from 0.
        let leaf = "V1\n# the base, 1 above\n4\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n0\n0\n1\n4 0 1 2 3\n";
        let mid = "V1\nload(\"leaf.cao\")\n1\n0.5 0.5 2 # apex\n2\n0 0\n0 0\n0\n0\n";
        let dir = folder(
            "two-levels",
            &[("parts/leaf.cao", leaf), ("parts/mid.cao", &mid.replace("2\n0 0\n0 0", "0")), ("top.cao", "")],
        );
        let top = "V1\nload(\"parts/mid.cao\")  # base and apex\n3\n5 0 0\n6 0 0\n5 1 0\n1\n0 1\n0\n1\n3 0 1 2\n";
        std::fs::write(dir.path().join("top.cao"), top).unwrap();
        let m = read_cao(&dir.path().join("top.cao")).unwrap();
        assert_eq!(m.name, "top");
        // Depth first: leaf's 4 points, mid's apex, then top's 3.
        assert_eq!(m.vertices.len(), 8);
        assert_eq!(m.vertices[0], [0.0, 0.0, 1.0]);
        assert_eq!(m.vertices[4], [0.5, 0.5, 2.0]);
        assert_eq!(m.vertices[5], [5.0, 0.0, 0.0]);
        // leaf's face as is; top's face and line offset by the 5 vertices before them.
        assert_eq!(m.faces, vec![vec![0, 1, 2, 3], vec![5, 6, 7]]);
        assert_eq!(m.edges, vec![[0, 1], [1, 2], [2, 3], [3, 0], [5, 6], [6, 7], [7, 5]]);
    }

    #[test]
    fn include_placements_compose_and_touching_parts_share_points() {
        // A 1 × 1 tile; two rows of two tiles: the row file places a second
        // tile 1 along x, and the top file a second row turned by 180° about
        // x and moved 2 along y (degrees, then radians, then R given by rows).
        let tile = "V1\n4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0\n0\n1\n4 0 1 2 3\n";
        let row = "V1\nload(\"tile.cao\")\nload(\"tile.cao\", t=[1; 0; 0])\n";
        for second_row in [
            "t=[0; 2; 0], tu=[180 deg; 0; 0]",
            "tu=[3.141592653589793rad;0;0], t=[0;2;0]",
            "t=[0; 2; 0], R=[1; 0; 0; 0; -1; 0; 0; 0; -1]",
        ] {
            let top = format!("V1\nload(\"row.cao\")\nload(\"row.cao\", {second_row})\n");
            let dir = folder("placements", &[("tile.cao", tile), ("row.cao", row), ("top.cao", &top)]);
            let m = read_cao(&dir.path().join("top.cao")).unwrap();
            // 3 × 3 grid points, each once: the tiles' shared corners are one vertex.
            assert_eq!(m.vertices.len(), 9, "{second_row}: {:?}", m.vertices);
            let mut grid: Vec<[i64; 3]> = m.vertices.iter().map(|v| v.map(|c| (c * 1e6).round() as i64)).collect();
            grid.sort_unstable();
            let expected: Vec<[i64; 3]> =
                (0..3).flat_map(|x| (0..3).map(move |y| [x * 1_000_000, y * 1_000_000, 0])).collect();
            assert_eq!(grid, expected, "{second_row}");
            // 4 tiles, each its own face; 12 distinct sides.
            assert_eq!(m.faces.len(), 4);
            assert_eq!(m.edges.len(), 12);
            // The second row is turned over: its faces face −z.
            let normal_z = |f: &Vec<usize>| {
                let (a, b, c) = (m.vertices[f[0]], m.vertices[f[1]], m.vertices[f[2]]);
                (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
            };
            assert!(m.faces[..2].iter().all(|f| normal_z(f) > 0.0) && m.faces[2..].iter().all(|f| normal_z(f) < 0.0));
        }
    }

    #[test]
    fn a_file_of_includes_only_is_a_model_and_a_file_of_nothing_is_not() {
        let dir = folder("only-includes", &[("square.cao", SQUARE), ("top.cao", "V1\nload(\"square.cao\")\n")]);
        assert_eq!(read_cao(&dir.path().join("top.cao")).unwrap().edges.len(), 4);
        let msg = err("V1\n0\n0\n0\n0\n");
        assert!(msg.starts_with("line 2: 0 3-D points"), "{msg}");
    }

    #[test]
    fn missing_and_cyclic_includes_name_the_including_file_and_line() {
        let dir = folder(
            "cycle",
            &[
                ("a.cao", "V1\n# a\nload(\"sub/b.cao\")\n0\n0\n0\n0\n"),
                ("sub/b.cao", "V1\nload(\"../square.cao\")\nload(\"../a.cao\")\n0\n0\n0\n0\n"),
                ("square.cao", SQUARE),
                ("c.cao", "V1\nload(\"nothere.cao\")\n"),
                ("self.cao", "V1\nload(\"self.cao\")\n"),
            ],
        );
        let (path, msg) = read_err(&dir.path().join("a.cao"));
        assert!(path.ends_with("sub/b.cao"), "{}", path.display());
        assert!(
            msg.starts_with("line 3: load(\"../a.cao\") makes a cycle of includes (a.cao → b.cao → a.cao)"),
            "{msg}"
        );
        let (path, msg) = read_err(&dir.path().join("c.cao"));
        assert!(path.ends_with("c.cao"));
        assert!(msg.starts_with("line 2: load(\"nothere.cao\"): no such file"), "{msg}");
        let (path, msg) = read_err(&dir.path().join("self.cao"));
        assert!(path.ends_with("self.cao") && msg.contains("(self.cao → self.cao)"), "{msg}");
    }

    #[test]
    fn errors_in_an_included_file_name_it() {
        let bad = SQUARE.replace("2 3\n", "2 9\n");
        let dir = folder("bad-part", &[("part.cao", &bad), ("top.cao", "V1\nload(\"part.cao\")\n")]);
        let (path, msg) = read_err(&dir.path().join("top.cao"));
        assert!(path.ends_with("part.cao"), "{}", path.display());
        assert!(msg.starts_with("line 10: 3-D line 2: point index 9 is out of range"), "{msg}");
        // A problem of the merged model names the part's file and line too.
        let flat = "V1\n5\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 0.5\n0\n0\n1\n5 0 1 2 3 4\n";
        let dir = folder("bent-part", &[("part.cao", flat), ("top.cao", "V1\nload(\"part.cao\")\n")]);
        let (path, msg) = read_err(&dir.path().join("top.cao"));
        assert!(path.ends_with("part.cao") && msg.starts_with("line 11: face 0 is not planar"), "{msg}");
    }

    #[test]
    fn misplaced_and_malformed_loads_are_refused() {
        let msg = err(&CUBE.replace("# 3D lines\n1", "load(\"part.cao\")\n1"));
        assert!(msg.starts_with("line 12: load(...) may stand only right after the V1 header"), "{msg}");
        let msg = err(&CUBE.replace("0 1 1\n", "load(\"part.cao\")\n"));
        assert!(msg.starts_with("line 6: load(...) may stand only"), "{msg}");
        for (load, needle) in [
            ("load(part.cao)", "in double quotes"),
            ("load(\"part.cao\"", "no closing parenthesis"),
            ("load(\"part.cao\", t=[1; 2])", "t= needs 3 values"),
            ("load(\"part.cao\", t=[1; 2; x])", "\"x\" is not a finite number"),
            ("load(\"part.cao\", t=[0; -2e9; 0])", "t=: -2.0e9 is beyond ±1.0e9"),
            ("load(\"part.cao\", s=[1; 2; 3])", "unknown parameter \"s\""),
            ("load(\"part.cao\", tu=[0; 0; 1], R=[1; 0; 0; 0; 1; 0; 0; 0; 1])", "give one rotation"),
            ("load(\"part.cao\", R=[1; 0; 0; 0; 2; 0; 0; 0; 1])", "not a rotation matrix"),
            ("load(\"\")", "the path is empty"),
        ] {
            let msg = err(&format!("V1\n{load}\n"));
            assert!(msg.starts_with("line 2: ") && msg.contains(needle), "{load}: {msg}");
        }
    }

    #[test]
    fn placement_of_a_point_is_rotation_then_translation() {
        let (_, p) = parse_load("load(\"p.cao\", t=[1; 2; 3], tu=[0; 0; 90deg])").unwrap();
        let q = p.apply([1.0, 0.0, 0.0]);
        // x turns to y, then moves by t.
        assert!((DVec3::from(q) - DVec3::new(1.0, 3.0, 3.0)).length() < 1e-12, "{q:?}");
        let outer = Placement { rotation: DMat3::IDENTITY, translation: DVec3::new(10.0, 0.0, 0.0) };
        let q = outer.after(&p).apply([1.0, 0.0, 0.0]);
        assert!((DVec3::from(q) - DVec3::new(11.0, 3.0, 3.0)).length() < 1e-12, "{q:?}");
    }

    #[test]
    fn files_included_many_times_over_are_refused() {
        // Each level includes the next twice: 2^20 readings.
        let mut files: Vec<(String, String)> = (0..20)
            .map(|k| (format!("l{k}.cao"), format!("V1\nload(\"l{}.cao\")\nload(\"l{}.cao\")\n", k + 1, k + 1)))
            .collect();
        files.push(("l20.cao".to_string(), SQUARE.to_string()));
        let files: Vec<(&str, &str)> = files.iter().map(|(p, t)| (p.as_str(), t.as_str())).collect();
        let dir = folder("many-times", &files);
        let (_, msg) = read_err(&dir.path().join("l0.cao"));
        assert!(msg.contains("more than 10000 files read"), "{msg}");
    }
}
