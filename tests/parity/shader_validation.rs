//! Every `shaders/*.wgsl` parses and validates with naga; a failure names
//! the file and the line.

use std::path::Path;

#[test]
fn every_shader_validates_with_naga() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("shaders/ exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no shaders found in {}", dir.display());
    let mut failures = Vec::new();
    for path in &files {
        let source = std::fs::read_to_string(path).expect("readable shader");
        let name = path.strip_prefix(env!("CARGO_MANIFEST_DIR")).unwrap_or(path).display().to_string();
        let module = match naga::front::wgsl::parse_str(&source) {
            Ok(m) => m,
            Err(e) => {
                let line = e.location(&source).map_or(0, |l| l.line_number);
                failures.push(format!("{name}:{line}: {}", e.emit_to_string(&source)));
                continue;
            }
        };
        let mut validator =
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty());
        if let Err(e) = validator.validate(&module) {
            let line = e.spans().next().map_or(0, |(span, _)| span.location(&source).line_number);
            failures.push(format!("{name}:{line}: {}", e.emit_to_string(&source)));
        }
    }
    assert!(failures.is_empty(), "shader validation failed:\n{}", failures.join("\n"));
}

#[test]
fn validator_reports_file_and_line_of_a_broken_shader() {
    let source = "@compute @workgroup_size(1)\nfn main() {\n  let x: f32 = 1u;\n}\n";
    let module = naga::front::wgsl::parse_str(source);
    let line = match module {
        Err(e) => e.location(source).map(|l| l.line_number),
        Ok(m) => {
            let mut v =
                naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty());
            v.validate(&m).err().and_then(|e| e.spans().next().map(|(s, _)| s.location(source).line_number))
        }
    };
    assert_eq!(line, Some(3));
}
