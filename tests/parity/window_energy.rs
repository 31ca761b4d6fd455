//! GPU/CPU parity of `shaders/window_energy.wgsl` (the `window_energy`
//! stage: warp N quadrilaterals, CPF to level k, energy against a template,
//! normalised over the windows) against its twin in src/early/window_energy.rs.
//!
//! Tolerances: filtered values `atol 1e-3` grey levels (chroma `1e-4`), and
//! energies `rtol 1e-4` of the largest energy. Both sides run the same loops
//! in the same order; the GPU's division and a possible fused multiply-add
//! move a sample position by a few ULPs, which moves a bilinear sample by
//! well under 10⁻³ grey levels; min and max pass such shifts through
//! unchanged in size.
use crate::common;

use pipetrack::RgbImage;
use pipetrack::early::window_energy::{
    self, CHANNELS, Quad, WindowEnergyParams, window_energy_cpu, window_energy_gpu, window_features_cpu,
    window_features_gpu,
};
use pipetrack::testimage::natural;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const VALUE_ATOL: f32 = 1e-3;
const CHROMA_ATOL: f32 = 1e-4;
const ENERGY_RTOL: f32 = 1e-4;

/// A colour frame of awkward size: three natural images as R, G, B.
fn colour_frame(w: usize, h: usize, seed: u64) -> RgbImage {
    let (r, g, b) = (natural(w, h, seed), natural(w, h, seed + 1), natural(w, h, seed + 2));
    RgbImage::from_fn(w, h, |x, y| [r.get(x, y), g.get(x, y), b.get(x, y)])
}

/// `n` windows around a 60-px square at (90, 80): jittered corners, some
/// partly or wholly outside the frame, some of zero area, some with three
/// corners in a line, some folded.
fn windows(n: usize, seed: u64) -> Vec<Quad> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let square: Quad = [[90.0, 80.0], [150.0, 80.0], [150.0, 140.0], [90.0, 140.0]];
    (0..n)
        .map(|i| match i % 10 {
            3 => {
                let p = [rng.random_range(-20.0..280.0), rng.random_range(-20.0..260.0)];
                [p; 4]
            }
            5 => {
                let (dx, dy) = (rng.random_range(-200.0..200.0), rng.random_range(-200.0..200.0));
                square.map(|[x, y]| [x + dx, y + dy])
            }
            7 => [[10.0, 10.0], [40.0, 10.0], [70.0, 10.0], [20.0, 50.0]],
            8 => [[90.0, 80.0], [150.0, 140.0], [150.0, 80.0], [90.0, 140.0]],
            _ => square.map(|[x, y]| [x + rng.random_range(-8.0..8.0), y + rng.random_range(-8.0..8.0)]),
        })
        .collect()
}

fn check_features(name: &str, cpu: &[f32], gpu: &[f32]) {
    assert_eq!(cpu.len(), gpu.len(), "{name}: length");
    let mut bad = Vec::new();
    for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
        let atol = if i % CHANNELS == 0 { VALUE_ATOL } else { CHROMA_ATOL };
        if !((c - g).abs() <= atol) {
            bad.push((i, *c, *g));
        }
    }
    assert!(bad.is_empty(), "{name}: {} values differ, first: {:?}", bad.len(), &bad[..bad.len().min(10)]);
}

fn parity_window_energy(n: usize, params: WindowEnergyParams) {
    let name = format!("parity_window_energy/n{n}/L{}k{}", params.side_log2, params.cpf_log2);
    let Some((ctx, _g)) = common::gpu(&name) else { return };
    let frame = colour_frame(257, 243, 40 + n as u64);
    let quads = windows(n, n as u64);
    let template_quad: Quad = [[92.0, 81.0], [151.0, 79.5], [149.0, 141.0], [89.0, 139.0]];
    let cpu_template = window_features_cpu(&frame, &params, &[template_quad]).unwrap().remove(0);
    let gpu_template = window_features_gpu(ctx, &frame, &params, &[template_quad]).unwrap().remove(0);
    check_features(&format!("{name}/template"), &cpu_template.values, &gpu_template.values);

    let cpu = window_energy_cpu(&frame, &quads, &cpu_template).unwrap();
    let gpu = window_energy_gpu(ctx, &frame, &quads, &cpu_template).unwrap();
    assert_eq!(gpu.energies.len(), n, "{name}: one energy per window");
    let largest = cpu.energies.iter().cloned().fold(0.0f32, f32::max);
    let bad: Vec<_> = cpu
        .energies
        .iter()
        .zip(&gpu.energies)
        .enumerate()
        .filter(|(_, (c, g))| !((*c - *g).abs() <= ENERGY_RTOL * largest))
        .map(|(i, (c, g))| (i, quads[i], *c, *g))
        .collect();
    assert!(bad.is_empty(), "{name}: {} energies differ, first: {:?}", bad.len(), &bad[..bad.len().min(10)]);
    for (what, c, g) in
        [("intensity", cpu.intensity_total, gpu.intensity_total), ("colour", cpu.colour_total, gpu.colour_total)]
    {
        assert!((c - g).abs() <= ENERGY_RTOL * c.abs(), "{name}: {what} total cpu {c} gpu {g}");
    }
    // The terms are normalised over the windows (eq. 25–26): energies sum to 2.
    let total: f32 = gpu.energies.iter().sum();
    assert!((total - 2.0).abs() < 1e-3, "{name}: energies sum to {total}");
}

#[test]
fn parity_window_energy_n1() {
    parity_window_energy(1, WindowEnergyParams { side_log2: 6, cpf_log2: 4 });
}

#[test]
fn parity_window_energy_n7_every_level() {
    for cpf_log2 in 1..=6 {
        parity_window_energy(7, WindowEnergyParams { side_log2: 6, cpf_log2 });
    }
}

#[test]
fn parity_window_energy_n200() {
    parity_window_energy(200, WindowEnergyParams { side_log2: 6, cpf_log2: 3 });
}

#[test]
fn parity_window_energy_n5000() {
    parity_window_energy(5000, WindowEnergyParams { side_log2: 4, cpf_log2: 2 });
}

/// Every window's filtered values, including those outside the frame and of
/// zero area, against the twin.
#[test]
fn parity_window_features_of_awkward_windows() {
    let Some((ctx, _g)) = common::gpu("parity_window_features_of_awkward_windows") else { return };
    let frame = colour_frame(257, 243, 5);
    let params = WindowEnergyParams { side_log2: 5, cpf_log2: 3 };
    let quads = windows(20, 9);
    let cpu = window_features_cpu(&frame, &params, &quads).unwrap();
    let gpu = window_features_gpu(ctx, &frame, &params, &quads).unwrap();
    for (i, (c, g)) in cpu.iter().zip(&gpu).enumerate() {
        check_features(&format!("window {i} {:?}", quads[i]), &c.values, &g.values);
    }
}

#[test]
fn parity_window_energy_refuses_what_the_twin_refuses() {
    let Some((ctx, _g)) = common::gpu("parity_window_energy_refuses_what_the_twin_refuses") else { return };
    let frame = colour_frame(9, 7, 1);
    let params = WindowEnergyParams { side_log2: 2, cpf_log2: 1 };
    let template =
        window_features_cpu(&frame, &params, &[[[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]]]).unwrap().remove(0);
    let nan: Quad = [[f32::NAN, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    assert!(window_energy_gpu(ctx, &frame, &[nan], &template).is_err());
    assert!(window_energy_cpu(&frame, &[nan], &template).is_err());
    let too_many = vec![[[0.0f32, 0.0]; 4]; window_energy::MAX_WINDOWS + 1];
    assert!(window_energy_gpu(ctx, &frame, &too_many, &template).is_err());
}

/// The stage inside a frame: both backends answer a frame's window request
/// (take a template, then score N windows) alike, on colour and on grey
/// frames; the GPU records the scoring as two dispatches in the frame's one
/// submission (after the frame's ingest) and reads back N energies and two sums.
#[test]
fn parity_window_energy_through_the_backends() {
    use pipetrack::backend::{CpuBackend, EarlyVision, FrameRequest, GpuBackend, WindowRequest};
    let Some((ctx, _g)) = common::gpu("parity_window_energy_through_the_backends") else { return };
    let frame = colour_frame(257, 243, 77);
    let params = WindowEnergyParams { side_log2: 5, cpf_log2: 3 };
    let template_quad: Quad = [[92.0, 81.0], [151.0, 79.5], [149.0, 141.0], [89.0, 139.0]];
    let features = FrameRequest {
        windows: Some(WindowRequest::Features { params, windows: vec![template_quad] }),
        ..FrameRequest::default()
    };
    let (mut cpu, mut gpu) = (CpuBackend::new(), GpuBackend::new(ctx.clone()));
    let c = cpu.process_rgb(&frame, &features).unwrap().window_features.unwrap().remove(0);
    let g = gpu.process_rgb(&frame, &features).unwrap().window_features.unwrap().remove(0);
    check_features("backend template", &c.values, &g.values);

    let n = 123;
    let energies = FrameRequest {
        windows: Some(WindowRequest::Energies { windows: windows(n, 3), template: std::sync::Arc::new(c) }),
        ..FrameRequest::default()
    };
    for grey in [false, true] {
        let (c, g) = if grey {
            let frame = frame.to_gray();
            (cpu.process(&frame, &energies).unwrap(), gpu.process(&frame, &energies).unwrap())
        } else {
            (cpu.process_rgb(&frame, &energies).unwrap(), gpu.process_rgb(&frame, &energies).unwrap())
        };
        let (c, g) = (c.window_energies.unwrap(), g.window_energies.unwrap());
        let largest = c.energies.iter().cloned().fold(0.0f32, f32::max);
        for (i, (a, b)) in c.energies.iter().zip(&g.energies).enumerate() {
            assert!((a - b).abs() <= ENERGY_RTOL * largest, "grey {grey}: window {i}: cpu {a} gpu {b}");
        }
        assert!((c.colour_total - g.colour_total).abs() <= ENERGY_RTOL * c.colour_total, "grey {grey}");
        let stats = gpu.last_frame_stats();
        // The frame's ingest, then window_terms and normalise.
        assert_eq!(stats.dispatches, 3, "grey {grey}");
        assert_eq!(stats.bytes_read_back, 4 * (n as u64 + 2), "grey {grey}");
    }
}

/// A colour frame's grey stages see exactly the luma a grey reading of it
/// gives: the features of any grey request are the same.
#[test]
fn colour_frames_leave_the_grey_stages_unchanged() {
    use pipetrack::backend::{CpuBackend, EarlyVision, FrameRequest, GpuBackend};
    let frame = colour_frame(64, 48, 3);
    let request = FrameRequest::full_chain(64, 48);
    let (mut a, mut b) = (CpuBackend::new(), CpuBackend::new());
    for _ in 0..2 {
        assert_eq!(a.process_rgb(&frame, &request).unwrap(), b.process(&frame.to_gray(), &request).unwrap());
    }
    let Some((ctx, _g)) = common::gpu("colour_frames_leave_the_grey_stages_unchanged") else { return };
    let (mut a, mut b) = (GpuBackend::new(ctx.clone()), GpuBackend::new(ctx.clone()));
    for _ in 0..2 {
        assert_eq!(a.process_rgb(&frame, &request).unwrap(), b.process(&frame.to_gray(), &request).unwrap());
    }
}

/// Sample windows in lanes of one submission: a colour lane scoring windows
/// and a grey lane filtering them (its grey frame read as colour) each answer
/// as the CPU backend does on that frame alone; a colour frame whose size is
/// not its luma's is refused before anything is recorded.
#[test]
fn parity_window_energy_in_lanes() {
    use pipetrack::backend::{CpuBackend, EarlyVision, FrameRequest, GpuBackend, LaneFrame, WindowRequest};
    let Some((ctx, _g)) = common::gpu("parity_window_energy_in_lanes") else { return };
    let colour = colour_frame(257, 243, 91);
    let luma = colour.to_gray();
    let grey = natural(257, 243, 92);
    let params = WindowEnergyParams { side_log2: 5, cpf_log2: 2 };
    let template_quad: Quad = [[92.0, 81.0], [151.0, 79.5], [149.0, 141.0], [89.0, 139.0]];
    let template = window_features_cpu(&colour, &params, &[template_quad]).unwrap().remove(0);
    let n = 57;
    let energies = FrameRequest {
        windows: Some(WindowRequest::Energies { windows: windows(n, 5), template: std::sync::Arc::new(template) }),
        ..FrameRequest::default()
    };
    let features = FrameRequest {
        windows: Some(WindowRequest::Features { params, windows: windows(9, 6) }),
        ..FrameRequest::default()
    };
    let mut gpu = GpuBackend::new(ctx.clone());
    let lanes = [
        LaneFrame { lane: 0, frame: &luma, colour: Some(&colour), request: &energies },
        LaneFrame { lane: 3, frame: &grey, colour: None, request: &features },
    ];
    let tickets = gpu.submit_lanes(&lanes).unwrap();
    let mut tickets = tickets.into_iter();
    let (scored, filtered) =
        (gpu.finish(tickets.next().unwrap()).unwrap(), gpu.finish(tickets.next().unwrap()).unwrap());

    let c = CpuBackend::new().process_rgb(&colour, &energies).unwrap().window_energies.unwrap();
    let g = scored.window_energies.unwrap();
    assert_eq!(g.energies.len(), n);
    let largest = c.energies.iter().cloned().fold(0.0f32, f32::max);
    for (i, (a, b)) in c.energies.iter().zip(&g.energies).enumerate() {
        assert!((a - b).abs() <= ENERGY_RTOL * largest, "colour lane: window {i}: cpu {a} gpu {b}");
    }
    assert!((c.colour_total - g.colour_total).abs() <= ENERGY_RTOL * c.colour_total, "colour lane: colour total");

    let c = CpuBackend::new().process(&grey, &features).unwrap().window_features.unwrap();
    let g = filtered.window_features.unwrap();
    assert_eq!(c.len(), g.len(), "grey lane: one filtered window each");
    for (i, (a, b)) in c.iter().zip(&g).enumerate() {
        check_features(&format!("grey lane window {i}"), &a.values, &b.values);
    }

    let small = colour_frame(64, 48, 1);
    let mismatched = [LaneFrame { lane: 1, frame: &luma, colour: Some(&small), request: &energies }];
    let err = gpu.submit_lanes(&mismatched).unwrap_err().to_string();
    assert!(err.contains("differ in size"), "{err}");
}
