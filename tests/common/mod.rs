//! Shared by the integration tests: one GPU context for the whole test
//! binary, and comparison helpers that explain their failures.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::{LazyLock, Mutex, MutexGuard};

use pipetrack::backend::EarlyVision;
use pipetrack::image::Image;
use pipetrack::io::formats::{FrameResult, Status};
use pipetrack::{AsFrame, GpuContext, Tracker};

static GPU: LazyLock<Option<GpuContext>> = LazyLock::new(|| match GpuContext::new() {
    Ok(ctx) => {
        eprintln!("GPU tests run on: {}", ctx.adapter_name());
        Some(ctx)
    }
    Err(e) => {
        if std::env::var("PIPETRACK_REQUIRE_GPU").is_ok_and(|v| v == "1") {
            panic!("PIPETRACK_REQUIRE_GPU=1 but no GPU adapter: {e}");
        }
        None
    }
});

/// GPU tests take this lock so they do not race on lavapipe.
static SERIAL: Mutex<()> = Mutex::new(());

/// The shared context and a lock serialising GPU tests, or `None` (printing
/// loudly that the test skipped) when there is no adapter and
/// `PIPETRACK_REQUIRE_GPU` is not `1`.
pub fn gpu(test: &str) -> Option<(&'static GpuContext, MutexGuard<'static, ()>)> {
    let guard = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    match GPU.as_ref() {
        Some(ctx) => Some((ctx, guard)),
        None => {
            eprintln!("SKIPPED {test}: no GPU adapter (set PIPETRACK_REQUIRE_GPU=1 to make this a failure)");
            None
        }
    }
}

/// The sizes every parity test covers: VGA, an odd size, and tiny ones
/// (kept in sync with the tests [`per_size!`] makes).
pub const PARITY_SIZES: &[(usize, usize)] = &[(640, 480), (257, 243), (1, 1), (2, 3)];

fn parity_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("parity");
    let _ = std::fs::create_dir_all(&dir);
    dir
}

/// Write a float image as a PNG, linearly scaled to its min..max.
fn write_png(path: &PathBuf, img: &Image<f32>) {
    let (w, h) = img.size();
    if w == 0 || h == 0 {
        return;
    }
    let lo = img.data().iter().cloned().fold(f32::INFINITY, f32::min);
    let hi = img.data().iter().cloned().fold(f32::NEG_INFINITY, f32::max);
    let scale = if hi > lo { 255.0 / (hi - lo) } else { 0.0 };
    let bytes: Vec<u8> = img.data().iter().map(|v| ((v - lo) * scale).clamp(0.0, 255.0) as u8).collect();
    let _ = image::save_buffer(path, &bytes, w as u32, h as u32, image::ColorType::L8);
}

/// Assert `|gpu − cpu| ≤ atol + rtol·|cpu|` everywhere (NaN never passes).
/// On failure: the first ten differences with coordinates, and
/// cpu/gpu/diff PNGs under `target/tmp/parity/`.
pub fn assert_close(name: &str, cpu: &Image<f32>, gpu: &Image<f32>, atol: f32, rtol: f32) {
    assert_eq!(cpu.size(), gpu.size(), "{name}: sizes differ");
    let w = cpu.width();
    let bad: Vec<(usize, f32, f32)> = cpu
        .data()
        .iter()
        .zip(gpu.data())
        .enumerate()
        .filter(|(_, (c, g))| !((*g - *c).abs() <= atol + rtol * c.abs()))
        .map(|(i, (c, g))| (i, *c, *g))
        .collect();
    if !bad.is_empty() {
        report(name, cpu, gpu, &bad, w);
    }
}

/// Like [`assert_close`] for angles: differences are taken modulo `period`
/// (2π for directions, π for undirected edge orientations), and pixels where
/// `weight` (the gradient magnitude) is below `min_weight` are not compared,
/// since their angle is ill-defined.
pub fn assert_angles_close(
    name: &str,
    cpu: &Image<f32>,
    gpu: &Image<f32>,
    weight: &Image<f32>,
    min_weight: f32,
    period: f32,
    atol: f32,
) {
    assert_eq!(cpu.size(), gpu.size(), "{name}: sizes differ");
    let w = cpu.width();
    let bad: Vec<(usize, f32, f32)> = cpu
        .data()
        .iter()
        .zip(gpu.data())
        .zip(weight.data())
        .enumerate()
        .filter(|(_, ((c, g), m))| {
            if **m < min_weight {
                return false;
            }
            let d = (*g - *c).rem_euclid(period);
            !(d.min(period - d) <= atol)
        })
        .map(|(i, ((c, g), _))| (i, *c, *g))
        .collect();
    if !bad.is_empty() {
        report(name, cpu, gpu, &bad, w);
    }
}

/// Exact comparison of two images of any comparable pixel type.
pub fn assert_equal<T: PartialEq + Copy + std::fmt::Debug + Default>(name: &str, cpu: &Image<T>, gpu: &Image<T>) {
    assert_eq!(cpu.size(), gpu.size(), "{name}: sizes differ");
    let w = cpu.width().max(1);
    let bad: Vec<String> = cpu
        .data()
        .iter()
        .zip(gpu.data())
        .enumerate()
        .filter(|(_, (c, g))| c != g)
        .take(10)
        .map(|(i, (c, g))| format!("  ({}, {}): cpu {c:?} gpu {g:?}", i % w, i / w))
        .collect();
    assert!(bad.is_empty(), "{name}: images differ; first differences:\n{}", bad.join("\n"));
}

fn report(name: &str, cpu: &Image<f32>, gpu: &Image<f32>, bad: &[(usize, f32, f32)], w: usize) {
    let dir = parity_dir();
    let stem = name.replace(['/', ' '], "_");
    write_png(&dir.join(format!("{stem}_cpu.png")), cpu);
    write_png(&dir.join(format!("{stem}_gpu.png")), gpu);
    let diff = Image::from_vec(
        cpu.width(),
        cpu.height(),
        cpu.data().iter().zip(gpu.data()).map(|(c, g)| (g - c).abs()).collect(),
    )
    .expect("same size");
    write_png(&dir.join(format!("{stem}_diff.png")), &diff);
    let lines: Vec<String> = bad
        .iter()
        .take(10)
        .map(|(i, c, g)| format!("  ({}, {}): cpu {c} gpu {g} diff {}", i % w, i / w, g - c))
        .collect();
    panic!(
        "{name}: {} of {} pixels out of tolerance; first ones:\n{}\nimages in {}",
        bad.len(),
        cpu.data().len(),
        lines.join("\n"),
        dir.display()
    );
}

/// One `#[test]` per size of [`PARITY_SIZES`], plus any `name = (w, h)`
/// given, each calling `$check(width, height)`, so that one failing size does
/// not hide the others: `per_size!(gaussian_parity);` makes the tests
/// `gaussian_parity::w640_h480`, `gaussian_parity::w257_h243`, ….
#[macro_export]
macro_rules! per_size {
    (@tests $check:ident $(; $name:ident = ($w:expr, $h:expr))*) => {
        $(
            #[test]
            fn $name() {
                super::$check($w, $h)
            }
        )*
    };
    ($check:ident $(; $name:ident = ($w:expr, $h:expr))*) => {
        mod $check {
            $crate::per_size!(@tests $check;
                w640_h480 = (640, 480); w257_h243 = (257, 243); w1_h1 = (1, 1); w2_h3 = (2, 3)
                $(; $name = ($w, $h))*);
        }
    };
}

/// A `w`×`h` 2-D texture of `format` that shaders can read and the queue can write.
pub fn empty_texture(ctx: &GpuContext, w: usize, h: usize, format: wgpu::TextureFormat) -> wgpu::Texture {
    ctx.device().create_texture(&wgpu::TextureDescriptor {
        label: Some("test frame"),
        size: wgpu::Extent3d { width: w as u32, height: h as u32, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

/// Write `bytes` (rows tightly packed) into all of `texture`.
pub fn write_texture(ctx: &GpuContext, texture: &wgpu::Texture, bytes: &[u8]) {
    let (w, h) = (texture.width() as usize, texture.height() as usize);
    let bytes_per_texel = bytes.len() / (w * h).max(1);
    ctx.queue().write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some((w * bytes_per_texel) as u32),
            rows_per_image: Some(h as u32),
        },
        texture.size(),
    );
}

/// A texture of `format` holding `bytes`.
pub fn texture(ctx: &GpuContext, w: usize, h: usize, format: wgpu::TextureFormat, bytes: &[u8]) -> wgpu::Texture {
    let t = empty_texture(ctx, w, h, format);
    write_texture(ctx, &t, bytes);
    t
}

/// Run the `pipetrack` binary with `args`; its status and output.
pub fn pipetrack(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_pipetrack")).args(args).output().expect("binary runs")
}

/// The partial files of output `name` in `dir` (every name that starts
/// with `<name>.partial`): what a finished or refused run must not leave.
pub fn partials(dir: &Path, name: &str) -> Vec<PathBuf> {
    let prefix = format!("{name}.partial");
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    entries.flatten().filter(|e| e.file_name().to_string_lossy().starts_with(&prefix)).map(|e| e.path()).collect()
}

/// [`pipetrack`] run in the folder `dir` (for relative paths).
pub fn pipetrack_in(dir: &Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("binary runs")
}

/// A fresh, empty scratch folder for one test, `pipetrack-<prefix>-<name>-XXXXXX`
/// under the system temp folder: removed with everything in it when the
/// value is dropped, so a passing test leaves nothing behind, and kept (its
/// path printed) when it is dropped by a failing test, to look at its files.
pub struct Scratch(Option<tempfile::TempDir>);

impl Scratch {
    pub fn path(&self) -> &Path {
        self.0.as_ref().expect("scratch folder present until dropped").path()
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;

    fn deref(&self) -> &Path {
        self.path()
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        self.path()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            return;
        }
        if let Some(dir) = self.0.take() {
            eprintln!("scratch folder of the failed test kept: {}", dir.keep().display());
        }
    }
}

/// A new [`Scratch`] folder for the test `name` of the group `prefix`.
pub fn scratch(prefix: &str, name: &str) -> Scratch {
    let dir = tempfile::Builder::new()
        .prefix(&format!("pipetrack-{prefix}-{name}-"))
        .tempdir()
        .expect("scratch folder in the temp folder");
    Scratch(Some(dir))
}

/// A 0.2 × 0.15 × 0.1 m box centred on its origin; vertex i has coordinate
/// signs from its bits (x: bit 0, y: bit 1, z: bit 2).
pub fn box_model() -> pipetrack::io::formats::Model {
    let half = [0.1, 0.075, 0.05];
    let vertices: Vec<[f64; 3]> =
        (0..8).map(|i| std::array::from_fn(|a| if (i >> a) & 1 == 1 { half[a] } else { -half[a] })).collect();
    let mut edges = Vec::new();
    for i in 0..8usize {
        for a in 0..3 {
            let j = i | (1 << a);
            if j != i {
                edges.push([i, j]);
            }
        }
    }
    // Faces: fixed axis a, side bit s; loop over the other two bits, oriented outward.
    let mut faces = Vec::new();
    for a in 0..3 {
        for s in 0..2usize {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            let corner = |u: usize, v: usize| (s << a) | (u << b) | (v << c);
            let mut face = vec![corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
            // (b, c, a) is a right-handed cycle: this loop's normal is +a; flip for the −a side.
            if s == 0 {
                face.reverse();
            }
            faces.push(face);
        }
    }
    pipetrack::io::formats::Model { name: "box".into(), units: "m".into(), vertices, edges, faces, joints: Vec::new() }
}

/// Track `frames` (`size` px) with `tracker` on `backend` through the real
/// per-frame loop: every frame's output line, and the frames not tracking
/// as `frame (reason)`, the reason from the output line (asserted present
/// on every lost line, absent on tracking ones).
pub fn track_lost<F: AsFrame>(
    tracker: &mut dyn Tracker,
    backend: &mut dyn EarlyVision,
    frames: impl IntoIterator<Item = F>,
    size: (usize, usize),
) -> (Vec<FrameResult>, Vec<String>) {
    let mut results = Vec::new();
    let mut lost = Vec::new();
    pipetrack::track::run::track_frames(tracker, backend, frames.into_iter().map(Ok), size, |_, _, result| {
        if result.status == Status::Tracking {
            assert_eq!(result.lost_reason, None, "frame {} is tracking", result.frame);
        } else {
            let why = result.lost_reason.as_deref().filter(|why| !why.is_empty());
            let why = why.unwrap_or_else(|| panic!("frame {} is lost without a reason in its line", result.frame));
            lost.push(format!("{} ({why})", result.frame));
        }
        results.push(result.clone());
        Ok(())
    })
    .expect("track");
    (results, lost)
}
