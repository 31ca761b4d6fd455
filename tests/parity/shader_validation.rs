//! Every shader the stages load ([`pipetrack::early::SHADERS`]) parses and
//! validates with naga as the device receives it (the file with its
//! includes appended), a failure naming the file and line it comes from; and
//! every host declaration (bindings per entry point, in binding order, with
//! their address space and access, and `@workgroup_size`) matches the shader.

use std::collections::BTreeMap;
use std::path::Path;

use pipetrack::early::{SHADERS, angle};
use pipetrack::gpu::{Binding, EntryPoint, Include, ShaderDef};

/// The composed module of `def`, parsed and validated; on failure,
/// `file:line: message` with the line in the file it comes from.
fn validate(def: &ShaderDef) -> Result<(naga::Module, naga::valid::ModuleInfo), String> {
    let source = def.composed_source();
    let at = |line: Option<u32>| {
        let (file, line) = def.locate(line.unwrap_or(0));
        format!("{file}:{line}")
    };
    let module = naga::front::wgsl::parse_str(&source)
        .map_err(|e| format!("{}: {}", at(e.location(&source).map(|l| l.line_number)), e.emit_to_string(&source)))?;
    let mut validator =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty());
    let info = validator.validate(&module).map_err(|e| {
        let line = e.spans().next().map(|(span, _)| span.location(&source).line_number);
        format!("{}: {}", at(line), e.emit_to_string(&source))
    })?;
    Ok((module, info))
}

/// What kind of [`Binding`] the global `var` is, or why it is none.
fn binding_kind(module: &naga::Module, var: &naga::GlobalVariable) -> Result<Binding, String> {
    match var.space {
        naga::AddressSpace::Uniform => Ok(Binding::Uniform),
        naga::AddressSpace::Storage { access } if access.contains(naga::StorageAccess::STORE) => Ok(Binding::Storage),
        naga::AddressSpace::Storage { .. } => Ok(Binding::ReadOnly),
        naga::AddressSpace::Handle => match module.types[var.ty].inner {
            naga::TypeInner::Image {
                dim: naga::ImageDimension::D2,
                arrayed: false,
                class: naga::ImageClass::Sampled { kind: naga::ScalarKind::Float, multi: false },
            } => Ok(Binding::Texture),
            ref other => Err(format!("unsupported handle type {other:?}")),
        },
        other => Err(format!("unsupported address space {other:?}")),
    }
}

/// Every difference between `def`'s declaration and its shader: entry points
/// missing on either side, workgroup sizes, and for each entry point the
/// bindings of group 0 it uses against those declared, binding by binding.
fn declaration_problems(def: &ShaderDef) -> Vec<String> {
    let (module, info) = match validate(def) {
        Ok(m) => m,
        Err(e) => return vec![e],
    };
    let file = def.path();
    let mut problems = Vec::new();
    for name in def.overrides {
        if !module.overrides.iter().any(|(_, o)| o.name.as_deref() == Some(*name)) {
            problems.push(format!("{file}: override `{name}` is declared but not in the shader"));
        }
    }
    for (_, o) in module.overrides.iter() {
        let name = o.name.as_deref().unwrap_or("?");
        if o.init.is_none() && !def.overrides.contains(&name) {
            problems.push(format!("{file}: override `{name}` has no default and is not declared"));
        }
    }
    for ep in &module.entry_points {
        if def.entry_point(&ep.name).is_none() {
            problems.push(format!("{file}: entry point `{}` is in the shader but not declared", ep.name));
        }
    }
    for declared in def.entry_points {
        let name = declared.name;
        let Some(index) = module.entry_points.iter().position(|e| e.name == name) else {
            problems.push(format!("{file}: entry point `{name}` is declared but not in the shader"));
            continue;
        };
        let ep = &module.entry_points[index];
        if ep.stage != naga::ShaderStage::Compute {
            problems.push(format!("{file}: `{name}` is a {:?} entry point, not compute", ep.stage));
        }
        if ep.workgroup_size != declared.workgroup_size {
            problems.push(format!(
                "{file}: `{name}` has @workgroup_size {:?}, the host dispatches {:?}",
                ep.workgroup_size, declared.workgroup_size
            ));
        }
        let uses = info.get_entry_point(index);
        let mut in_shader: BTreeMap<u32, Result<Binding, String>> = BTreeMap::new();
        for (handle, var) in module.global_variables.iter() {
            let Some(rb) = &var.binding else { continue };
            if uses[handle].is_empty() {
                continue;
            }
            if rb.group != 0 {
                problems.push(format!(
                    "{file}: `{name}` uses group {} binding {}; only group 0 is bound",
                    rb.group, rb.binding
                ));
                continue;
            }
            in_shader.insert(rb.binding, binding_kind(&module, var));
        }
        let count = in_shader.keys().next_back().map_or(0, |&b| b as usize + 1).max(declared.bindings.len());
        for i in 0..count {
            let shader = in_shader.get(&(i as u32));
            let host = declared.bindings.get(i);
            let same = matches!((shader, host), (Some(Ok(s)), Some(h)) if s == h);
            if !same {
                problems.push(format!(
                    "{file}: `{name}` binding {i}: declared {host:?}, shader {}",
                    match shader {
                        None => "does not use it".to_string(),
                        Some(kind) => format!("{kind:?}"),
                    }
                ));
            }
        }
    }
    problems
}

#[test]
fn every_shader_validates_with_naga() {
    let includes: Vec<Include> = SHADERS.iter().flat_map(|d| d.includes.iter().copied()).collect();
    let mut failures: Vec<String> = SHADERS.iter().filter_map(|d| validate(d).err()).collect();
    // Each include also stands alone as a module of its own.
    for include in &includes {
        let alone =
            ShaderDef { name: include.name, source: include.source, includes: &[], entry_points: &[], overrides: &[] };
        failures.extend(validate(&alone).err());
    }
    assert!(failures.is_empty(), "shader validation failed:\n{}", failures.join("\n"));
}

#[test]
fn every_wgsl_file_is_a_declared_shader_or_an_include() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut stems: Vec<String> = std::fs::read_dir(&dir)
        .expect("shaders/ exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();
    stems.sort();
    let mut known: Vec<String> = SHADERS
        .iter()
        .map(|d| d.name.to_string())
        .chain(SHADERS.iter().flat_map(|d| d.includes.iter().map(|i| i.name.to_string())))
        .collect();
    known.sort();
    known.dedup();
    assert_eq!(stems, known, "shaders/*.wgsl against the ShaderDefs and their includes");
    for def in SHADERS {
        let on_disk = std::fs::read_to_string(dir.join(format!("{}.wgsl", def.name))).expect("readable shader");
        assert_eq!(def.source, on_disk, "{}: the ShaderDef's source is not the file", def.path());
    }
}

#[test]
fn declared_bindings_and_workgroup_sizes_match_every_shader() {
    let problems: Vec<String> = SHADERS.iter().flat_map(declaration_problems).collect();
    assert!(problems.is_empty(), "host declarations differ from the shaders:\n{}", problems.join("\n"));
}

#[test]
fn a_wrong_declaration_is_caught() {
    use Binding::{ReadOnly, Storage, Texture, Uniform};
    let sobel = pipetrack::early::sobel::SHADER;
    assert!(declaration_problems(&sobel).is_empty());

    // The source read as writable, one output plane forgotten, a wrong tile.
    const WRONG: &[EntryPoint] = &[EntryPoint {
        name: "sobel",
        workgroup_size: [8, 8, 1],
        bindings: &[Uniform, Storage, Storage, Storage, Storage, Storage],
    }];
    let problems = declaration_problems(&ShaderDef { entry_points: WRONG, ..sobel });
    let expected = [
        "`sobel` has @workgroup_size [16, 16, 1], the host dispatches [8, 8, 1]",
        "`sobel` binding 1: declared Some(Storage), shader Ok(ReadOnly)",
        "`sobel` binding 6: declared None, shader Ok(Storage)",
    ];
    assert_eq!(problems.len(), expected.len(), "{problems:#?}");
    for (p, e) in problems.iter().zip(expected) {
        assert!(p.starts_with("shaders/sobel.wgsl: ") && p.ends_with(e), "{p:?} should end with {e:?}");
    }

    // A binding the entry point does not use, and entry points on one side only.
    const EXTRA: &[EntryPoint] = &[
        EntryPoint::tiled("sobel", &[Uniform, ReadOnly, Storage, Storage, Storage, Storage, Storage, Texture]),
        EntryPoint::tiled("gradient", &[Uniform]),
    ];
    let problems = declaration_problems(&ShaderDef { entry_points: EXTRA, ..sobel });
    assert_eq!(
        problems,
        [
            "shaders/sobel.wgsl: `sobel` binding 7: declared Some(Texture), shader does not use it",
            "shaders/sobel.wgsl: entry point `gradient` is declared but not in the shader",
        ]
    );
    let problems = declaration_problems(&ShaderDef { entry_points: &[], ..sobel });
    assert_eq!(problems, ["shaders/sobel.wgsl: entry point `sobel` is in the shader but not declared"]);

    // An overridable constant the shader does not have, and one it has
    // without a default that the host would not set.
    let problems = declaration_problems(&ShaderDef { overrides: &["COMPACTION_RUN"], ..sobel });
    assert_eq!(problems, ["shaders/sobel.wgsl: override `COMPACTION_RUN` is declared but not in the shader"]);
    assert!(declaration_problems(&pipetrack::early::compaction::SHADER).is_empty());
    const UNSET_ENTRY: &[EntryPoint] = &[EntryPoint::linear("main", 1, &[])];
    let unset = ShaderDef {
        name: "unset",
        source: "override N: u32;\n@compute @workgroup_size(1)\nfn main() {\n  let x = N;\n}\n",
        includes: &[],
        entry_points: UNSET_ENTRY,
        overrides: &[],
    };
    assert_eq!(declaration_problems(&unset), ["shaders/unset.wgsl: override `N` has no default and is not declared"]);
}

#[test]
fn validator_reports_file_and_line_of_a_broken_shader() {
    let broken = ShaderDef {
        name: "broken",
        source: "@compute @workgroup_size(1)\nfn main() {\n  let x: f32 = 1u;\n}\n",
        includes: &[],
        entry_points: &[],
        overrides: &[],
    };
    let err = validate(&broken).expect_err("a u32 is not an f32");
    assert!(err.starts_with("shaders/broken.wgsl:3: "), "{err}");
}

/// An error inside an include names the include and its own line, not the
/// line of the composed module; one in the file keeps the file's line.
#[test]
fn validator_reports_file_and_line_inside_an_include() {
    const BROKEN: Include = Include { name: "broken_include", source: "// one\n// two\nconst Z: f32 = 1u;\n" };
    let source = "// the file\n@compute @workgroup_size(1)\nfn main() {\n  let a = fast_atan(Z);\n}\n";
    let def =
        ShaderDef { name: "file", source, includes: &[angle::INCLUDE, BROKEN], entry_points: &[], overrides: &[] };
    let err = validate(&def).expect_err("a u32 is not an f32");
    assert!(err.starts_with("shaders/broken_include.wgsl:3: "), "{err}");

    let def = ShaderDef {
        name: "file",
        source: "const Y: i32 = 1.5;\n",
        includes: &[angle::INCLUDE],
        entry_points: &[],
        overrides: &[],
    };
    let err = validate(&def).expect_err("1.5 is not an i32");
    assert!(err.starts_with("shaders/file.wgsl:1: "), "{err}");
}
