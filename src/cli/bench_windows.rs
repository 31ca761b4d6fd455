//! `pipetrack bench --windows N,...`: the `window_energy` stage as the
//! Condensation tracker runs it — one frame of a `textured-plane` view, N
//! sample windows of 64 × 64 compared at CPF level 16 × 16 against a
//! template — on the CPU backend and the GPU backend (one submission per
//! frame: frame and window upload, the two dispatches, N energies read
//! back), side by side.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{DMat3, DVec3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::Result;
use crate::backend::{CpuBackend, EarlyVision, FrameRequest, GpuBackend, WindowRequest};
use crate::early::window_energy::{WindowEnergyParams, window_features_cpu};
use crate::geometry::pose::Pose;
use crate::image::RgbImage;
use crate::synth::textured_plane::{DEPTH_M, camera, model, render_view};
use crate::track::condensation::steps;

/// One row: N windows on both backends.
#[derive(Clone, Debug, Serialize)]
pub struct WindowBenchRow {
    /// Number of windows.
    pub windows: usize,
    /// Milliseconds per frame on the CPU backend.
    pub cpu_ms: f64,
    /// Milliseconds per frame on the GPU backend (none without an adapter).
    pub gpu_ms: Option<f64>,
    /// The GPU's frames per second over the CPU's (CPU time over GPU time),
    /// as the stage rows of `bench` give it: above 1, the GPU is faster.
    pub gpu_over_cpu: Option<f64>,
}

/// What `bench --windows` measured, in the shape of `bench`'s own report.
#[derive(Clone, Debug, Serialize)]
pub struct WindowBenchReport {
    /// The GPU adapter, or why there is none.
    pub adapter: String,
    /// CPU threads used by the CPU backend.
    pub cpu_threads: usize,
    /// One row per number of windows, in the order asked.
    pub rows: Vec<WindowBenchRow>,
}

/// Mean time of `body` over at least three calls and at least `budget`.
fn time(budget: Duration, mut body: impl FnMut() -> Result<()>) -> Result<f64> {
    body()?;
    let (start, mut calls) = (Instant::now(), 0u32);
    while calls < 3 || start.elapsed() < budget {
        body()?;
        calls += 1;
    }
    Ok(start.elapsed().as_secs_f64() * 1e3 / f64::from(calls))
}

/// The frame and the request with `n` windows around the scene's window.
fn setup(n: usize) -> Result<(RgbImage, FrameRequest)> {
    let pose = Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.0, DEPTH_M));
    let frame = render_view(1, 1.5, &pose, 0)?;
    let cam = camera();
    let vertices = model().vertices;
    let corners: [[f64; 2]; 4] = std::array::from_fn(|i| cam.project(pose.apply(DVec3::from_array(vertices[i]))));
    let params = WindowEnergyParams::default();
    let quad = corners.map(|c| [c[0] as f32, c[1] as f32]);
    let template = window_features_cpu(&frame, &params, &[quad])?.remove(0);
    let sigma = steps::component_sigmas(&cam, &corners, &[DEPTH_M; 4], 2.0, &[1.0; 6]);
    let samples = steps::draw_initial_samples(&[0.0; 6], &sigma, n, &mut ChaCha8Rng::seed_from_u64(7));
    let windows = steps::project_sample_windows(&cam, &corners, &[DEPTH_M; 4], &samples);
    let request = FrameRequest {
        windows: Some(WindowRequest::Energies { windows, template: Arc::new(template) }),
        ..FrameRequest::default()
    };
    Ok((frame, request))
}

/// Time the stage at each N of `counts` for at least `budget` per backend
/// (the CPU alone when `gpu` is false, or when there is no adapter).
pub fn bench_windows(
    counts: &[usize],
    budget: Duration,
    gpu: bool,
    mut row: impl FnMut(&WindowBenchRow),
) -> Result<WindowBenchReport> {
    let (adapter, gpu) = super::bench::open_gpu(gpu);
    let mut rows = Vec::new();
    for &n in counts {
        let (frame, request) = setup(n)?;
        let mut cpu = CpuBackend::new();
        let cpu_ms = time(budget, || cpu.process_rgb(&frame, &request).map(|_| ()))?;
        let gpu_ms = match &gpu {
            Some(ctx) => {
                let mut backend = GpuBackend::new(ctx.clone());
                Some(time(budget, || backend.process_rgb(&frame, &request).map(|_| ()))?)
            }
            None => None,
        };
        let r = WindowBenchRow { windows: n, cpu_ms, gpu_ms, gpu_over_cpu: gpu_ms.map(|g| cpu_ms / g) };
        row(&r);
        rows.push(r);
    }
    Ok(WindowBenchReport { adapter, cpu_threads: rayon::current_num_threads(), rows })
}
