//! What the host declares about each WGSL shader: its file, the shared
//! snippets it includes, and for every entry point its workgroup size and
//! its bindings in binding order.
//!
//! The declaration is the single source the host works from: the pipeline
//! cache builds every bind-group layout from it, the recorder checks each
//! dispatch's resources against it, and `tests/shader_validation.rs` checks
//! it against the shader itself with naga (bindings, their address space and
//! access, and `@workgroup_size`), so host and shader cannot drift apart.

use std::borrow::Cow;

use super::TILE;

/// One binding of bind group 0, as the shader declares it. Binding `i` of an
/// entry point is the `i`-th element of [`EntryPoint::bindings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Binding {
    /// `var<uniform>`: the stage's parameter block (binding 0 of every entry point).
    Uniform,
    /// `var<storage, read>`: a buffer the entry point only reads.
    ReadOnly,
    /// `var<storage, read_write>`: a buffer the entry point writes.
    Storage,
    /// `texture_2d<f32>` read with `textureLoad` (any float-sampled format,
    /// filterable or not).
    Texture,
}

impl Binding {
    /// The bind-group layout entry for this binding at index `binding`,
    /// visible to the compute stage.
    #[must_use]
    pub fn layout_entry(self, binding: u32) -> wgpu::BindGroupLayoutEntry {
        let buffer = |ty| wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None };
        let ty = match self {
            Self::Uniform => buffer(wgpu::BufferBindingType::Uniform),
            Self::ReadOnly => buffer(wgpu::BufferBindingType::Storage { read_only: true }),
            Self::Storage => buffer(wgpu::BufferBindingType::Storage { read_only: false }),
            Self::Texture => wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
        };
        wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::COMPUTE, ty, count: None }
    }

    /// Whether a storage or uniform buffer goes here (not a texture).
    #[must_use]
    pub fn is_buffer(self) -> bool {
        self != Self::Texture
    }
}

/// One `@compute` entry point of a shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EntryPoint {
    /// The WGSL function name.
    pub name: &'static str,
    /// Its `@workgroup_size`, which the host's dispatch grid assumes.
    pub workgroup_size: [u32; 3],
    /// The bindings of group 0 it uses, in binding order (0, 1, …).
    pub bindings: &'static [Binding],
}

impl EntryPoint {
    /// An entry point over 2-D tiles of [`TILE`]×[`TILE`] invocations, one
    /// per pixel (dispatched over `workgroups_2d(width, height)`).
    #[must_use]
    pub const fn tiled(name: &'static str, bindings: &'static [Binding]) -> Self {
        Self { name, workgroup_size: [TILE, TILE, 1], bindings }
    }

    /// An entry point of 8×8 invocations per [`TILE`]×[`TILE`] tile of the
    /// first level it builds (each invocation builds a 2×2 block of it),
    /// dispatched over `workgroups_2d` of that level's size: the pyramid
    /// shaders, which then reduce the tile in workgroup memory.
    #[must_use]
    pub const fn pyramid_levels(name: &'static str, bindings: &'static [Binding]) -> Self {
        Self { name, workgroup_size: [TILE / 2, TILE / 2, 1], bindings }
    }

    /// An entry point over 1-D workgroups of `size` invocations.
    #[must_use]
    pub const fn linear(name: &'static str, size: u32, bindings: &'static [Binding]) -> Self {
        Self { name, workgroup_size: [size, 1, 1], bindings }
    }
}

/// A WGSL file of shared declarations (constants and functions, no
/// bindings or entry points) that shaders include.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Include {
    /// File stem in `shaders/`, e.g. `"angle"`.
    pub name: &'static str,
    /// The WGSL source (`include_str!`).
    pub source: &'static str,
}

/// One WGSL shader file of a stage, and what the host declares about it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderDef {
    /// File stem in `shaders/`, e.g. `"sobel"`; pipelines are labelled
    /// `pipetrack.<name>.<entry point>`.
    pub name: &'static str,
    /// The WGSL source of the file itself (`include_str!`).
    pub source: &'static str,
    /// Shared files appended to `source` when the module is built, in order.
    pub includes: &'static [Include],
    /// Every entry point the host dispatches.
    pub entry_points: &'static [EntryPoint],
    /// The shader's pipeline-overridable constants (WGSL `override`
    /// declarations) that the context sets when it compiles a pipeline,
    /// each to the value [`super::GpuContext`] chose for its device.
    pub overrides: &'static [&'static str],
}

/// `source` as composed, ending in exactly one line break more than it has
/// lines (so the next part starts on a line of its own).
fn with_final_newline(source: &str) -> Cow<'_, str> {
    if source.is_empty() || source.ends_with('\n') { Cow::Borrowed(source) } else { Cow::Owned(format!("{source}\n")) }
}

/// Lines `source` occupies in the composed module.
fn line_count(source: &str) -> u32 {
    with_final_newline(source).matches('\n').count() as u32
}

impl ShaderDef {
    /// The file's path relative to the crate root, e.g. `shaders/sobel.wgsl`.
    #[must_use]
    pub fn path(&self) -> String {
        format!("shaders/{}.wgsl", self.name)
    }

    /// The declaration of entry point `name`, if declared.
    #[must_use]
    pub fn entry_point(&self, name: &str) -> Option<&'static EntryPoint> {
        self.entry_points.iter().find(|e| e.name == name)
    }

    /// The WGSL module the device compiles: the file first, then each
    /// include. The file comes first so that its line numbers are the same in
    /// the composed module as on disk; WGSL declarations may appear in any
    /// order, so the file can use what its includes declare.
    #[must_use]
    pub fn composed_source(&self) -> Cow<'static, str> {
        if self.includes.is_empty() {
            return Cow::Borrowed(self.source);
        }
        let mut out = with_final_newline(self.source).into_owned();
        for include in self.includes {
            out.push_str(&with_final_newline(include.source));
        }
        Cow::Owned(out)
    }

    /// The file and its 1-based line that hold 1-based `line` of
    /// [`ShaderDef::composed_source`], e.g. `("shaders/angle.wgsl", 12)`.
    /// Lines past the end are attributed to the last part.
    #[must_use]
    pub fn locate(&self, line: u32) -> (String, u32) {
        let mut first = 1;
        let own = line_count(self.source);
        if line < first + own || self.includes.is_empty() {
            return (self.path(), line);
        }
        first += own;
        for (i, include) in self.includes.iter().enumerate() {
            let n = line_count(include.source);
            if line < first + n || i + 1 == self.includes.len() {
                return (format!("shaders/{}.wgsl", include.name), line - first + 1);
            }
            first += n;
        }
        (self.path(), line)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: Include = Include { name: "a", source: "const A1: f32 = 1.0;\nconst A2: f32 = 2.0;\n" };
    const B: Include = Include { name: "b", source: "const B1: f32 = 3.0;" };

    #[test]
    fn composed_source_appends_includes_and_lines_map_back_to_their_files() {
        let def = ShaderDef {
            name: "s",
            source: "// s line 1\n// s line 2",
            includes: &[A, B],
            entry_points: &[],
            overrides: &[],
        };
        let composed = def.composed_source();
        assert_eq!(
            composed,
            "// s line 1\n// s line 2\nconst A1: f32 = 1.0;\nconst A2: f32 = 2.0;\nconst B1: f32 = 3.0;\n"
        );
        let located: Vec<(String, u32)> = (1..=5).map(|l| def.locate(l)).collect();
        let expected = [("s", 1), ("s", 2), ("a", 1), ("a", 2), ("b", 1)];
        for ((file, line), (stem, want)) in located.iter().zip(expected) {
            assert_eq!((file.as_str(), *line), (format!("shaders/{stem}.wgsl").as_str(), want));
        }
        let plain = ShaderDef { includes: &[], ..def };
        assert_eq!(plain.composed_source(), plain.source);
        assert_eq!(plain.locate(2), ("shaders/s.wgsl".to_string(), 2));
    }

    #[test]
    fn entry_points_are_found_by_name_and_tiles_use_the_host_tile() {
        const BINDINGS: &[Binding] = &[Binding::Uniform, Binding::Storage];
        const DEF: ShaderDef = ShaderDef {
            name: "s",
            source: "",
            includes: &[],
            entry_points: &[EntryPoint::tiled("a", BINDINGS), EntryPoint::linear("b", 64, BINDINGS)],
            overrides: &[],
        };
        let def = DEF;
        assert_eq!(def.entry_point("a").map(|e| e.workgroup_size), Some([TILE, TILE, 1]));
        assert_eq!(def.entry_point("b").map(|e| e.workgroup_size), Some([64, 1, 1]));
        assert!(def.entry_point("c").is_none());
    }
}
