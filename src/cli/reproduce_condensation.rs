//! `pipetrack reproduce condensation`: 004's Fig. 4 on a synthetic scene —
//! the energy of every sample window against its pose error, at CPF levels
//! l = 1..6 of a 64 × 64 window.
//!
//! Set-up, as 004 §IV: a source image of the `textured-plane` scene
//! (0.6 m away, 400 px focal length: the 64 × 64 px window of
//! [`crate::synth::textured_plane`]), a destination image after a camera
//! translation of 10 mm in x and −10 mm in y, and 200 samples of the screw
//! drawn around the known motion with a large variance in x and y and none
//! in the other components. Each sample's window (eq. 20–21) is scored
//! against the source window at level l (eq. 22–26); its *pose error* is the
//! distance between its translation and the true one, in mm. The samples
//! are the same at every level.
//!
//! Writes `fig4.csv` (level, sample, error_mm, energy) and one scatter plot
//! per level, `fig4_l<l>.png` (x: error 0..[`PLOT_MAX_ERROR_MM`] mm, a tick
//! every 5 mm; y: energy 0 at the bottom to the level's largest at the top),
//! and returns a summary per level.

use std::fmt::Write as _;
use std::path::Path;

use glam::{DMat3, DVec3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::early::window_energy::{WindowEnergyParams, window_energy_cpu, window_features_cpu};
use crate::geometry::pose::Pose;
use crate::io::StagedDir;
use crate::synth::textured_plane::{DEPTH_M, camera, model, render_view};
use crate::track::condensation::steps;
use crate::{Error, Result};

/// The camera's translation between source and destination, m (004 §IV).
pub const CAMERA_TRANSLATION_M: [f64; 3] = [0.010, -0.010, 0.0];
/// Samples (004 §IV: n = 200).
pub const SAMPLES: usize = 200;
/// Standard deviation of the samples' x and y translation around the true one, m.
pub const SPREAD_M: f64 = 0.008;
/// The window is 2^6 = 64 px a side.
pub const WINDOW_LEVEL: u32 = 6;
/// Right end of the plots' error axis, mm.
pub const PLOT_MAX_ERROR_MM: f64 = 30.0;
/// Noise of the rendered images, grey levels per channel.
const NOISE: f64 = 1.5;

/// One sample at one level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fig4Point {
    /// CPF level l.
    pub level: u32,
    /// Pose error of the sample, mm.
    pub error_mm: f64,
    /// Its energy U (eq. 22).
    pub energy: f64,
}

/// Score the samples at every level; `seed` picks the texture and the samples.
pub fn fig4_points(seed: u64) -> Result<Vec<Fig4Point>> {
    let start = Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.0, DEPTH_M));
    let [tx, ty, tz] = CAMERA_TRANSLATION_M;
    let moved_camera = Pose::new(DMat3::IDENTITY, DVec3::new(tx, ty, tz));
    let destination_pose = moved_camera.inverse().compose(&start);
    let source = render_view(seed, NOISE, &start, 0)?;
    let destination = render_view(seed, NOISE, &destination_pose, 1)?;
    let cam = camera();
    let vertices = model().vertices;
    let corners: [[f64; 2]; 4] = std::array::from_fn(|i| cam.project(start.apply(DVec3::from_array(vertices[i]))));
    let depths = [DEPTH_M; 4];
    let truth = steps::screw_of_camera_motion(&[tx, ty, tz, 0.0, 0.0, 0.0]);
    let sigma = [SPREAD_M, SPREAD_M, 0.0, 0.0, 0.0, 0.0];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let samples = steps::draw_initial_samples(&truth, &sigma, SAMPLES, &mut rng);
    let windows = steps::project_sample_windows(&cam, &corners, &depths, &samples);
    let errors: Vec<f64> = samples.iter().map(|s| 1e3 * (s[0] - truth[0]).hypot(s[1] - truth[1])).collect();
    let source_quad = corners.map(|c| [c[0] as f32, c[1] as f32]);
    let mut points = Vec::new();
    for level in 1..=WINDOW_LEVEL {
        let params = WindowEnergyParams { side_log2: WINDOW_LEVEL, cpf_log2: level };
        let template = window_features_cpu(&source, &params, &[source_quad])?.remove(0);
        let energies = window_energy_cpu(&destination, &windows, &template)?;
        points.extend(errors.iter().zip(&energies.energies).map(|(&e, &u)| Fig4Point {
            level,
            error_mm: e,
            energy: f64::from(u),
        }));
    }
    Ok(points)
}

/// Write `fig4.csv` and the plots into the new folder `out` (refused when it
/// exists and is not empty; nothing appears unless everything was written),
/// and return the markdown summary.
pub fn reproduce_fig4(out: &Path, seed: u64) -> Result<String> {
    let staged = StagedDir::create(out)?;
    let points = fig4_points(seed)?;
    let mut csv = String::from("level,sample,error_mm,energy\n");
    for (i, p) in points.iter().enumerate() {
        let _ = writeln!(csv, "{},{},{:.4},{:.6e}", p.level, i % SAMPLES, p.error_mm, p.energy);
    }
    let csv_path = staged.path().join("fig4.csv");
    std::fs::write(&csv_path, csv).map_err(|e| Error::io(&csv_path, e))?;
    for level in 1..=WINDOW_LEVEL {
        let at: Vec<&Fig4Point> = points.iter().filter(|p| p.level == level).collect();
        let path = staged.path().join(format!("fig4_l{level}.png"));
        scatter(&at).save(&path).map_err(|e| Error::io(&path, std::io::Error::other(e)))?;
    }
    staged.finish()?;
    Ok(summary(&points))
}

/// Per level: the median energy of samples within 5 mm, 5–10 mm, 10–15 mm
/// and beyond 15 mm of the truth (relative to the whole level's median),
/// and the error of the lowest-energy sample.
#[must_use]
pub fn summary(points: &[Fig4Point]) -> String {
    let mut md = String::from(
        "| l | median U / median U of all, error < 5 mm | 5–10 mm | 10–15 mm | > 15 mm | error of min-U sample, mm |\n|---|---|---|---|---|---|\n",
    );
    for level in 1..=WINDOW_LEVEL {
        let at: Vec<&Fig4Point> = points.iter().filter(|p| p.level == level).collect();
        let all = median(at.iter().map(|p| p.energy).collect());
        let band = |lo: f64, hi: f64| {
            let v: Vec<f64> = at.iter().filter(|p| p.error_mm >= lo && p.error_mm < hi).map(|p| p.energy).collect();
            if v.is_empty() { "–".to_string() } else { format!("{:.2} ({})", median(v.clone()) / all, v.len()) }
        };
        let best = at.iter().min_by(|a, b| a.energy.total_cmp(&b.energy)).map_or(f64::NAN, |p| p.error_mm);
        let _ = writeln!(
            md,
            "| {level} | {} | {} | {} | {} | {best:.2} |",
            band(0.0, 5.0),
            band(5.0, 10.0),
            band(10.0, 15.0),
            band(15.0, f64::INFINITY)
        );
    }
    md
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Plot size and margin, px.
const PLOT_W: u32 = 480;
const PLOT_H: u32 = 320;
const MARGIN: u32 = 24;

/// A scatter plot of energy against error: axes, a tick every 5 mm, a dot per sample.
fn scatter(points: &[&Fig4Point]) -> image::RgbImage {
    let mut img = image::RgbImage::from_pixel(PLOT_W, PLOT_H, image::Rgb([255, 255, 255]));
    let black = image::Rgb([0, 0, 0]);
    let (x0, y0, x1, y1) = (MARGIN, MARGIN / 2, PLOT_W - MARGIN / 2, PLOT_H - MARGIN);
    for x in x0..=x1 {
        img.put_pixel(x, y1, black);
    }
    for y in y0..=y1 {
        img.put_pixel(x0, y, black);
    }
    let to_x = |e: f64| f64::from(x0) + (e / PLOT_MAX_ERROR_MM).clamp(0.0, 1.0) * f64::from(x1 - x0);
    let mut tick = 0.0;
    while tick <= PLOT_MAX_ERROR_MM {
        let x = to_x(tick) as u32;
        let length = if (tick % 10.0).abs() < 1e-9 { 8 } else { 4 };
        for y in y1..(y1 + length).min(PLOT_H) {
            img.put_pixel(x, y, black);
        }
        tick += 5.0;
    }
    let top = points.iter().map(|p| p.energy).fold(0.0f64, f64::max).max(f64::MIN_POSITIVE);
    for p in points {
        let x = to_x(p.error_mm) as i64;
        let y = f64::from(y1) - (p.energy / top) * f64::from(y1 - y0);
        let y = y as i64;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (px, py) = (x + dx, y + dy);
                if px >= 0 && py >= 0 && (px as u32) < PLOT_W && (py as u32) < PLOT_H {
                    img.put_pixel(px as u32, py as u32, image::Rgb([200, 30, 30]));
                }
            }
        }
    }
    img
}
