//! Tracking logic of the `motion-edge` tracker (paper 000) on synthetic
//! motion-pixel streams, without images or a GPU.
//!
//! The generator renders what the backend would list, analytically: a convex
//! polygon of contrast 100 grey levels on a uniform background, blurred by a
//! Gaussian-like edge profile (σ = 1); a pixel is a motion pixel when the
//! temporal difference of the two blurred frames exceeds 10 (eq. 1); its θ and
//! magnitude come from the gradient of the *sum* of the two frames (eq. 2),
//! θ = atan(gy/gx) + π/2 wrapped into [0, π), plus ±2° noise. Where the sum is
//! flat (inside wide bands) the gradient vanishes; there θ is random and the
//! magnitude noise-sized, as sensor noise would make it. Random clutter pixels
//! with random θ are added over the window. Only pixels inside the tracker's
//! window of interest are handed over, row-major, as the backend does.

use pipetrack::early::Feature;
use pipetrack::io::formats::Status;
use pipetrack::track::{
    FrameOutcome, LineFitMethod, MissingMeasurement, MotionEdgeParams, MotionEdgeTracker, Observations, Phase,
    Prediction, Tracker,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

const CONTRAST: f64 = 100.0;
const DIFF_THRESHOLD: f64 = 10.0;
const BLUR: f64 = 1.0;
const IMAGE: usize = 4000;

/// Smooth step Φ(x) (logistic approximation of the normal CDF).
fn phi(x: f64) -> f64 {
    1.0 / (1.0 + (-1.702 * x).exp())
}

/// Blurred coverage of the convex polygon `poly` (either orientation) at `p`.
fn coverage(poly: &[[f64; 2]], p: [f64; 2]) -> f64 {
    let n = poly.len();
    let area2: f64 = (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    let sign = area2.signum();
    // Inward signed distance to the boundary: the minimum over edges.
    let d = (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = dx.hypot(dy);
            sign * (dx * (p[1] - a[1]) - dy * (p[0] - a[0])) / len
        })
        .fold(f64::INFINITY, f64::min);
    phi(d / BLUR)
}

/// The motion pixels between frames with polygons `before` and `after`, plus
/// `clutter` random pixels, restricted to the tracker's window.
fn motion_features(
    before: &[[f64; 2]],
    after: &[[f64; 2]],
    tracker: &MotionEdgeTracker,
    clutter: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Feature> {
    let window = tracker.window_of_interest(IMAGE, IMAGE);
    let mut features = Vec::new();
    let all: Vec<[f64; 2]> = before.iter().chain(after).copied().collect();
    let lo = |k: usize| all.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min) - 6.0;
    let hi = |k: usize| all.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max) + 6.0;
    let (x0, x1) = ((lo(0).floor().max(window.x0 as f64)) as u32, (hi(0).ceil().min(window.x1 as f64 - 1.0)) as u32);
    let (y0, y1) = ((lo(1).floor().max(window.y0 as f64)) as u32, (hi(1).ceil().min(window.y1 as f64 - 1.0)) as u32);
    let sum = |p: [f64; 2]| CONTRAST * (coverage(before, p) + coverage(after, p));
    let mut pixels: Vec<(u32, u32, f32, f32)> = Vec::new();
    if x0 <= x1 && y0 <= y1 && lo(0) < window.x1 as f64 && lo(1) < window.y1 as f64 {
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = [f64::from(x), f64::from(y)];
                let diff = CONTRAST * (coverage(after, p) - coverage(before, p));
                if diff.abs() <= DIFF_THRESHOLD {
                    continue;
                }
                let h = 0.5;
                let gx = (sum([p[0] + h, p[1]]) - sum([p[0] - h, p[1]])) / (2.0 * h);
                let gy = (sum([p[0], p[1] + h]) - sum([p[0], p[1] - h])) / (2.0 * h);
                // Sobel on a unit-spaced grid is ≈ 8× the derivative.
                let magnitude = 8.0 * gx.hypot(gy);
                let (theta, magnitude) = if magnitude < 15.0 {
                    (rng.random_range(0.0..PI), rng.random_range(0.0..15.0))
                } else {
                    let noise = rng.random_range(-2.0f64..2.0).to_radians();
                    ((gy.atan2(gx) + PI / 2.0 + noise).rem_euclid(PI), magnitude)
                };
                pixels.push((x, y, theta as f32, magnitude as f32));
            }
        }
    }
    for _ in 0..clutter {
        if window.is_empty() {
            break;
        }
        let x = rng.random_range(window.x0..window.x1);
        let y = rng.random_range(window.y0..window.y1);
        pixels.push((x, y, rng.random_range(0.0..PI) as f32, rng.random_range(10.0..300.0) as f32));
    }
    // Row-major, one entry per pixel, as compaction lists them.
    pixels.sort_by_key(|&(x, y, _, _)| (y, x));
    pixels.dedup_by_key(|&mut (x, y, _, _)| (x, y));
    features.extend(pixels.into_iter().map(|(x, y, theta, magnitude)| Feature { x, y, theta, magnitude }));
    features
}

/// A square of side `side` centred at `centre`, turned by `angle` radians.
fn square(centre: [f64; 2], side: f64, angle: f64) -> Vec<[f64; 2]> {
    let h = side / 2.0;
    [[-h, -h], [h, -h], [h, h], [-h, h]]
        .iter()
        .map(|&[x, y]| [centre[0] + x * angle.cos() - y * angle.sin(), centre[1] + x * angle.sin() + y * angle.cos()])
        .collect()
}

const SQUARE_EDGES: [[usize; 2]; 4] = [[0, 1], [1, 2], [2, 3], [3, 0]];

fn corner_error(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1])).sum::<f64>() / a.len() as f64
}

/// Run the tracker over the truth `polygons` (frame 0 first); frame 0 gets no
/// motion pixels. Returns every outcome.
fn run(polygons: &[Vec<[f64; 2]>], params: MotionEdgeParams, clutter: usize, seed: u64) -> Vec<FrameOutcome> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut tracker = MotionEdgeTracker::new(polygons[0].clone(), SQUARE_EDGES.to_vec(), params).expect("valid model");
    let mut outcomes = vec![tracker.update(0, &[])];
    for t in 1..polygons.len() {
        let motion = motion_features(&polygons[t - 1], &polygons[t], &tracker, clutter, &mut rng);
        let outcome = tracker.track(t, &Observations { motion: Some(&motion), ..Observations::default() });
        outcomes.push(outcome);
    }
    outcomes
}

/// Translation at `speed` px/frame along 65° below +x, square turned 20°:
/// 45° to both edge directions, so every edge has motion pixels (an edge
/// moving along itself has none: the aperture problem).
fn translating(speed: f64, frames: usize) -> Vec<Vec<[f64; 2]>> {
    let dir = MOTION_DIRECTION;
    (0..frames)
        .map(|t| {
            square([300.0 + speed * dir[0] * t as f64, 300.0 + speed * dir[1] * t as f64], 80.0, 20f64.to_radians())
        })
        .collect()
}

fn mean_error_after(outcomes: &[FrameOutcome], truth: &[Vec<[f64; 2]>], warm_up: usize) -> f64 {
    let errors: Vec<f64> =
        outcomes[warm_up..].iter().zip(&truth[warm_up..]).map(|(o, t)| corner_error(&o.corners, t)).collect();
    errors.iter().sum::<f64>() / errors.len() as f64
}

const WARM_UP: usize = 10;

/// Unit vector 65° below +x.
const MOTION_DIRECTION: [f64; 2] = [0.422_618_261_740_699_4, 0.906_307_787_036_649_9];

#[test]
fn moving_square_is_tracked_within_half_a_pixel_at_paper_and_higher_speeds() {
    for (i, speed) in [1.1, 3.9, 4.5, 8.0, 16.0].into_iter().enumerate() {
        let truth = translating(speed, 50);
        let outcomes = run(&truth, MotionEdgeParams::default(), 60, 7 + i as u64);
        for o in &outcomes {
            assert_eq!(o.status, Status::Tracking, "speed {speed}: frame {} {:?}", o.frame, o.diagnostics);
        }
        assert_eq!(outcomes.last().map(|o| o.phase), Some(Phase::Tracking));
        let mean = mean_error_after(&outcomes, &truth, WARM_UP);
        println!("speed {speed:>4} px/frame: mean corner error {mean:.3} px after frame {WARM_UP}");
        assert!(mean <= 0.5, "speed {speed}: mean corner error {mean:.3} px");
        // Frame 0 reports the operator's corners exactly.
        assert_eq!(outcomes[0].corners, truth[0]);
    }
}

#[test]
fn lag_correction_removes_the_half_frame_lag() {
    let speed = 8.0;
    let truth = translating(speed, 40);
    let corrected = mean_error_after(&run(&truth, MotionEdgeParams::default(), 0, 1), &truth, WARM_UP);
    let paper = MotionEdgeParams { lag_correction: false, ..MotionEdgeParams::default() };
    let uncorrected = mean_error_after(&run(&truth, paper, 0, 1), &truth, WARM_UP);
    println!("v = {speed}: uncorrected {uncorrected:.3} px (v/2 = {}), corrected {corrected:.3} px", speed / 2.0);
    // Lines fitted to motion pixels sit half a frame back: error ≈ v/2.
    assert!((uncorrected - speed / 2.0).abs() < 0.5, "uncorrected error {uncorrected:.3}, expected ≈ {}", speed / 2.0);
    assert!(corrected < 0.1 * speed / 2.0, "corrected error {corrected:.3} not ≪ v/2");
}

#[test]
fn pendulum_swing_with_turning_points_keeps_tracking() {
    // x(t) = 400 + 60·sin(0.075·t): peak 4.5 px/frame, turning points every 42 frames.
    let truth: Vec<Vec<[f64; 2]>> =
        (0..120).map(|t| square([400.0 + 60.0 * (0.075 * t as f64).sin(), 300.0], 80.0, 10f64.to_radians())).collect();
    let outcomes = run(&truth, MotionEdgeParams::default(), 60, 3);
    for o in &outcomes {
        assert_eq!(o.status, Status::Tracking, "frame {} {:?}", o.frame, o.diagnostics);
    }
    let mean = mean_error_after(&outcomes, &truth, WARM_UP);
    let worst = outcomes.iter().zip(&truth).map(|(o, t)| corner_error(&o.corners, t)).fold(0.0, f64::max);
    println!("pendulum: mean corner error {mean:.3} px, worst frame {worst:.3} px");
    assert!(mean <= 0.5, "mean corner error {mean:.3}");
    assert!(worst <= 1.0, "worst frame error {worst:.3}");
}

#[test]
fn a_60_px_jump_is_lost_without_panicking() {
    // Moving at 4 px/frame, then 60 px further along the motion in one frame.
    let speed = 4.0;
    let dir = MOTION_DIRECTION;
    let jump = [60.0 * dir[0], 60.0 * dir[1]];
    let truth: Vec<Vec<[f64; 2]>> = (0..50)
        .map(|t| {
            let off = if t >= 25 { jump } else { [0.0, 0.0] };
            square(
                [300.0 + speed * dir[0] * t as f64 + off[0], 300.0 + speed * dir[1] * t as f64 + off[1]],
                80.0,
                20f64.to_radians(),
            )
        })
        .collect();
    let outcomes = run(&truth, MotionEdgeParams::default(), 60, 5);
    assert_eq!(outcomes.len(), truth.len(), "an outcome for every frame");
    assert!(outcomes[..25].iter().all(|o| o.status == Status::Tracking), "tracking before the jump");
    let first_lost = outcomes.iter().position(|o| o.status == Status::Lost).expect("the jump must be lost");
    println!("jump at frame 25, first lost frame {first_lost}: {:?}", outcomes[first_lost].diagnostics.lost_reason);
    assert!((25..=28).contains(&first_lost), "lost at frame {first_lost}");
    for o in &outcomes[first_lost..] {
        assert_eq!(o.corners.len(), 4);
        assert!(o.corners.iter().all(|c| c[0].is_finite() && c[1].is_finite()));
    }
    // It stays lost: nothing matches the coasting prediction.
    assert_eq!(outcomes.last().map(|o| o.status), Some(Status::Lost));
}

#[test]
fn clutter_alone_does_not_move_a_resting_model() {
    let truth: Vec<Vec<[f64; 2]>> = (0..20).map(|_| square([200.0, 200.0], 80.0, 0.2)).collect();
    let outcomes = run(&truth, MotionEdgeParams::default(), 150, 11);
    for o in &outcomes {
        assert_eq!(o.status, Status::Tracking, "frame {} {:?}", o.frame, o.diagnostics);
        assert!(corner_error(&o.corners, &truth[0]) < 1e-9, "frame {} moved: {:?}", o.frame, o.corners);
    }
}

#[test]
fn printed_fits_and_predictions_track_translating_lines_at_the_paper_speeds() {
    // Eq. 4–8 fits and eq. 12 predictions as printed (one labelling pass,
    // fixed ζ, regression fits, coasting on predictions) with the lag
    // correction kept, on hand-made motion pixels of a translating square;
    // `MotionEdgeParams::paper()` is the whole method as printed.
    let paper = MotionEdgeParams {
        line_fit: LineFitMethod::Regression,
        refine_iterations: 0,
        band_tolerance: false,
        missing: MissingMeasurement::Prediction,
        prediction: Prediction::Smoothed,
        ..MotionEdgeParams::default()
    };
    for (i, speed) in [1.1, 3.9, 4.5].into_iter().enumerate() {
        let truth = translating(speed, 50);
        let outcomes = run(&truth, paper.clone(), 60, 20 + i as u64);
        assert!(outcomes.iter().all(|o| o.status == Status::Tracking), "speed {speed}");
        let mean = mean_error_after(&outcomes, &truth, WARM_UP);
        println!("printed fits and predictions, speed {speed:>4} px/frame: mean corner error {mean:.3} px");
        assert!(mean <= 0.5, "speed {speed}: mean corner error {mean:.3} px");
    }
}

/// `pipetrack reproduce motion-edge` on a tiny grid: deterministic, one
/// table per ε with the paper's row and both metrics per configuration.
#[test]
fn reproduce_tables_on_a_tiny_grid_are_deterministic() {
    use pipetrack::cli::reproduce::{Config, Setup, markdown, run_one, run_tables, scene};
    use pipetrack::synth::pendulum::render_pendulum;

    let setup = Setup {
        speeds: vec![3.9],
        zetas: vec![5.0],
        epsilons: vec![20.0, 32.0],
        seeds: vec![1, 2],
        frames: 24,
        configs: vec![Config::Paper, Config::Default],
    };
    let first = run_tables(&setup, &|_, _| {}).expect("tables");
    let second = run_tables(&setup, &|_, _| {}).expect("tables");
    assert_eq!(first, second, "same setup, same runs");
    let md = markdown(&first);
    assert_eq!(md, markdown(&second));
    println!("{md}");
    assert!(md.contains("#### Table 1 — corner error (px), ε = 20"), "{md}");
    assert!(md.contains("#### Table 3 — corner error (px), ε = 32"), "{md}");
    // The paper's Table 1 figure for 3.9 px/frame, ζ = 5.
    assert!(md.contains("| 3.9 | paper's table | 0.096 |"), "{md}");
    for name in ["paper", "default"] {
        assert!(md.contains(&format!("| 3.9 | `{name}` predicted − extracted |")), "{md}");
        assert!(md.contains(&format!("| 3.9 | `{name}` reported − truth |")), "{md}");
    }

    // Each cell is the run of its own seed's sequence: seed 2, ε = 32, default.
    let seq = render_pendulum(&scene(3.9, 2, 24)).expect("scene");
    let params = MotionEdgeParams { zeta: 5.0, epsilon: 32.0, ..MotionEdgeParams::default() };
    let run = run_one(&seq, &params).expect("run");
    assert_eq!(first.cell(1, 1, 0, 0)[1], run);
    // 24 frames of the start of the swing: tracked throughout, measured on most.
    assert_eq!(run.tracked, 24);
    assert!(run.measured_frames >= 12 && run.measured_frames < 24, "{run:?}");
    assert!(run.truth_error < 1.0 && run.paper_error < 1.0, "{run:?}");
    // The `paper` configuration (no lag correction) gives numbers too.
    let paper = first.cell(0, 0, 0, 0)[0];
    assert!(paper.paper_error.is_finite() && paper.truth_error.is_finite(), "{paper:?}");

    let empty = Setup { seeds: Vec::new(), ..setup };
    assert!(run_tables(&empty, &|_, _| {}).is_err());
}

#[test]
fn paper_configuration_has_every_switchable_extension_off() {
    let p = MotionEdgeParams::paper();
    p.validate().expect("valid");
    assert_eq!(p.line_fit, LineFitMethod::Regression);
    assert_eq!(p.refine_iterations, 0);
    assert!(!p.band_tolerance && !p.lag_correction);
    assert_eq!(p.prediction, Prediction::Smoothed);
    assert_eq!(p.missing, MissingMeasurement::LastMeasurement);
    assert_eq!(p.lost_evidence, pipetrack::track::motion_edge::MAX_COUNT);
    assert_eq!(p.vanished_motion, f64::INFINITY);
    assert_eq!((p.zeta, p.epsilon, p.alpha), (5.0, 20.0, 0.2));
}
