//! The synthetic-scene renderer (`pipetrack synth`) and the overlay drawer.
//!
//! Tolerances: coverage grey levels are exact (hand-computed, edges on
//! multiples of 1/S); the intensity-weighted centroid of a rendered rectangle
//! matches the mean of its truth corners within 0.05 px (noise 0); the measured
//! peak corner speed equals the requested speed within 2 % (the contract; by
//! construction it is exact, checked to 1e-6 relative).

use std::path::{Path, PathBuf};

use pipetrack::Error;
use pipetrack::image::{FloatImage, GrayImage};
use pipetrack::io::formats::{Camera, InitState, Model, Status, TruthFrame};
use pipetrack::io::overlay::{self, draw_overlay};
use pipetrack::synth::pendulum::{self, HEIGHT, JUMP_OFFSET_PX, TARGET_GREY, WIDTH};
use pipetrack::synth::{
    self, BACKGROUND_GREY, Background, Canvas, Face, FillRule, PendulumMotion, PendulumOptions, PendulumSwing,
    add_noise_and_quantise, render_pendulum,
};

/// Render a canvas down to u8 without noise.
fn to_gray(canvas: &Canvas) -> GrayImage {
    let smooth: FloatImage = canvas.downsample();
    let mut out = GrayImage::new(0, 0);
    add_noise_and_quantise(&smooth, 0.0, &mut synth::frame_rng(0, 0), &mut out);
    out
}

fn rows(img: &GrayImage) -> Vec<Vec<u8>> {
    (0..img.height()).map(|y| img.row(y).to_vec()).collect()
}

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> [[f64; 2]; 4] {
    [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
}

#[test]
fn synth_supersample_centres_follow_the_pixel_centre_convention() {
    let canvas = Canvas::new(3, 2, 4, 0.0).unwrap();
    // Pixel 0 spans [-0.5, 0.5]: its four samples sit at -0.375, -0.125, 0.125, 0.375.
    assert_eq!(canvas.sample_centre(0, 0), [-0.375, -0.375]);
    assert_eq!(canvas.sample_centre(3, 1), [0.375, -0.125]);
    assert_eq!(canvas.sample_centre(4, 7), [0.625, 1.375]);
}

#[test]
fn synth_rectangle_on_pixel_boundaries_is_crisp() {
    // x in [1.5, 4.5], y in [0.5, 3.5]: exactly pixels x = 2..4, y = 1..3.
    let mut canvas = Canvas::new(7, 5, 4, 0.0).unwrap();
    canvas.fill_polygon(&rect(1.5, 0.5, 4.5, 3.5), FillRule::EvenOdd, 200.0);
    let expected: Vec<Vec<u8>> = vec![
        vec![0, 0, 0, 0, 0, 0, 0],
        vec![0, 0, 200, 200, 200, 0, 0],
        vec![0, 0, 200, 200, 200, 0, 0],
        vec![0, 0, 200, 200, 200, 0, 0],
        vec![0, 0, 0, 0, 0, 0, 0],
    ];
    assert_eq!(rows(&to_gray(&canvas)), expected);
}

#[test]
fn synth_partial_coverage_is_area_weighted() {
    // x in [1.75, 5.0]: covers 3/4 of column 2, columns 3-4, 1/2 of column 5.
    // y in [1.0, 3.25]: covers 1/2 of row 1, row 2, 3/4 of row 3.
    // Grey = 160 · (x coverage) · (y coverage) over a black background.
    let mut canvas = Canvas::new(7, 5, 4, 0.0).unwrap();
    canvas.fill_polygon(&rect(1.75, 1.0, 5.0, 3.25), FillRule::EvenOdd, 160.0);
    let expected: Vec<Vec<u8>> = vec![
        vec![0, 0, 0, 0, 0, 0, 0],
        vec![0, 0, 60, 80, 80, 40, 0],
        vec![0, 0, 120, 160, 160, 80, 0],
        vec![0, 0, 90, 120, 120, 60, 0],
        vec![0, 0, 0, 0, 0, 0, 0],
    ];
    assert_eq!(rows(&to_gray(&canvas)), expected);
    // The float image before rounding is exact too.
    assert_eq!(canvas.downsample().get(2, 1), 60.0);
}

#[test]
fn synth_coverage_mixes_with_the_background() {
    // Edge at x = 2.0 halves column 2: (100 + 220) / 2 = 160.
    let mut canvas = Canvas::new(4, 1, 4, 100.0).unwrap();
    canvas.fill_polygon(&rect(2.0, -0.5, 3.5, 0.5), FillRule::EvenOdd, 220.0);
    assert_eq!(rows(&to_gray(&canvas)), vec![vec![100, 100, 160, 220]]);
}

#[test]
fn synth_non_convex_polygon_and_fill_rules() {
    // An L: the 3x3 block of pixels 1..3 minus its top-right 2x2 (pixels x 2..3, y 1..2).
    let l_shape = [[0.5, 0.5], [1.5, 0.5], [1.5, 2.5], [3.5, 2.5], [3.5, 3.5], [0.5, 3.5]];
    let mut canvas = Canvas::new(5, 5, 4, 0.0).unwrap();
    canvas.fill_polygon(&l_shape, FillRule::EvenOdd, 90.0);
    let expected: Vec<Vec<u8>> = vec![
        vec![0, 0, 0, 0, 0],
        vec![0, 90, 0, 0, 0],
        vec![0, 90, 0, 0, 0],
        vec![0, 90, 90, 90, 0],
        vec![0, 0, 0, 0, 0],
    ];
    assert_eq!(rows(&to_gray(&canvas)), expected);

    // The same square outline walked twice: winding number 2 inside, so
    // even-odd leaves it empty and non-zero fills it.
    let square = rect(0.5, 0.5, 2.5, 2.5);
    let twice: Vec<[f64; 2]> = square.iter().chain(square.iter()).copied().collect();
    let mut even_odd = Canvas::new(4, 4, 4, 0.0).unwrap();
    even_odd.fill_polygon(&twice, FillRule::EvenOdd, 50.0);
    assert!(to_gray(&even_odd).data().iter().all(|&v| v == 0));
    let mut non_zero = Canvas::new(4, 4, 4, 0.0).unwrap();
    non_zero.fill_polygon(&twice, FillRule::NonZero, 50.0);
    let filled = to_gray(&non_zero);
    assert_eq!(filled.get(1, 1), 50);
    assert_eq!(filled.get(2, 2), 50);
    assert_eq!(filled.get(3, 3), 0);
}

#[test]
fn synth_adjacent_faces_share_edges_without_gaps_or_overlap() {
    // Two triangles splitting the square of pixels 1..3 along its diagonal,
    // drawn as one layer, give a solid square: the diagonal cells get 1/2 + 1/2.
    let upper = [[0.5, 0.5], [3.5, 0.5], [3.5, 3.5]];
    let lower = [[0.5, 0.5], [3.5, 3.5], [0.5, 3.5]];
    let mut canvas = Canvas::new(5, 5, 4, 0.0).unwrap();
    canvas.fill_faces(&[Face { points: &upper, grey: 200.0 }, Face { points: &lower, grey: 200.0 }], FillRule::EvenOdd);
    let img = to_gray(&canvas);
    for y in 0..5 {
        for x in 0..5 {
            let inside = (1..4).contains(&x) && (1..4).contains(&y);
            assert_eq!(img.get(x, y), if inside { 200 } else { 0 }, "pixel ({x},{y})");
        }
    }
    // Different greys meet on the diagonal: a diagonal pixel is half of each.
    let mut canvas = Canvas::new(5, 5, 4, 0.0).unwrap();
    canvas.fill_faces(&[Face { points: &upper, grey: 200.0 }, Face { points: &lower, grey: 100.0 }], FillRule::EvenOdd);
    let smooth = canvas.downsample();
    assert!((smooth.get(2, 2) - 150.0).abs() < 1e-3, "{}", smooth.get(2, 2));
    assert_eq!(smooth.get(3, 1), 200.0);
    assert_eq!(smooth.get(1, 3), 100.0);
}

#[test]
fn synth_slanted_edge_coverage_is_exact() {
    // A triangle with legs along x = 0.5 and y = 0.5 and hypotenuse
    // x + y = 4 from (0.5, 3.5) to (3.5, 0.5): pixels (1,1), (2,1), (1,2) lie
    // inside, the hypotenuse halves (3,1), (2,2), (1,3) through their corners,
    // and the total area is 3 · 3 / 2 = 4.5 pixels.
    let mut canvas = Canvas::new(5, 5, 4, 0.0).unwrap();
    canvas.fill_polygon(&[[0.5, 0.5], [3.5, 0.5], [0.5, 3.5]], FillRule::NonZero, 100.0);
    let smooth = canvas.downsample();
    let close = |x: usize, y: usize, v: f32| {
        assert!((smooth.get(x, y) - v).abs() < 1e-4, "pixel ({x},{y}) = {}, want {v}", smooth.get(x, y));
    };
    close(1, 1, 100.0);
    close(2, 1, 100.0);
    close(1, 2, 100.0);
    close(3, 1, 50.0);
    close(2, 2, 50.0);
    close(1, 3, 50.0);
    close(3, 2, 0.0);
    let total: f32 = smooth.data().iter().sum();
    assert!((total - 450.0).abs() < 1e-3, "{total}");
    // An edge off the 1/S grid: x = 2.1 leaves 0.4 of column 2 covered.
    let mut canvas = Canvas::new(4, 1, 4, 0.0).unwrap();
    canvas.fill_polygon(&rect(2.1, -0.5, 3.5, 0.5), FillRule::EvenOdd, 100.0);
    assert!((canvas.downsample().get(2, 0) - 40.0).abs() < 1e-4);
}

#[test]
fn synth_degenerate_polygons_draw_nothing() {
    let mut canvas = Canvas::new(4, 4, 4, 7.0).unwrap();
    canvas.fill_polygon(&[[0.0, 0.0], [3.0, 3.0]], FillRule::EvenOdd, 200.0);
    canvas.fill_polygon(&[[f64::NAN, 0.0], [3.0, 0.0], [3.0, 3.0]], FillRule::EvenOdd, 200.0);
    canvas.fill_polygon(&rect(-1e300, -1e300, 1e300, -1e299), FillRule::NonZero, 200.0);
    assert!(to_gray(&canvas).data().iter().all(|&v| v == 7));
    // Far outside but finite: clipped, the visible part is filled.
    canvas.fill_polygon(&rect(-1e9, -1e9, 1e9, 1e9), FillRule::EvenOdd, 9.0);
    assert!(to_gray(&canvas).data().iter().all(|&v| v == 9));
    assert!(Canvas::new(0, 4, 4, 0.0).is_err());
    assert!(Canvas::new(4, 4, 0, 0.0).is_err());
}

fn quiet(speed: f64, motion: PendulumMotion) -> PendulumOptions {
    PendulumOptions { speed, motion, noise_sigma: 0.0, background: Background::Flat, ..PendulumOptions::default() }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn peak_corner_speed(truth: &[TruthFrame]) -> f64 {
    truth.windows(2).flat_map(|w| w[0].corners.iter().zip(&w[1].corners).map(|(a, b)| dist(*a, *b))).fold(0.0, f64::max)
}

#[test]
fn synth_pendulum_truth_corners_match_the_rendered_rectangle() {
    for motion in [PendulumMotion::Rotating, PendulumMotion::Translating] {
        let seq = render_pendulum(&PendulumOptions { frames: 64, ..quiet(3.9, motion) }).unwrap();
        for k in [0, 7, 15, 30, 31, 45, 63] {
            let frame = &seq.frames[k];
            let (mut sum, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
            for y in 0..frame.height() {
                for x in 0..frame.width() {
                    let wgt = f64::from(frame.get(x, y)) - f64::from(BACKGROUND_GREY);
                    sum += wgt;
                    sx += wgt * x as f64;
                    sy += wgt * y as f64;
                }
            }
            let corners = &seq.truth[k].corners;
            let mean =
                [corners.iter().map(|c| c[0]).sum::<f64>() / 4.0, corners.iter().map(|c| c[1]).sum::<f64>() / 4.0];
            let centroid = [sx / sum, sy / sum];
            assert!(
                dist(centroid, mean) < 0.05,
                "{motion:?} frame {k}: centroid {centroid:?} vs mean of corners {mean:?}"
            );
            // The covered area is the rectangle's 50 x 35 px.
            let area = sum / f64::from(TARGET_GREY - BACKGROUND_GREY);
            assert!((area - 1750.0).abs() < 2.0, "{motion:?} frame {k}: area {area}");
        }
    }
}

#[test]
fn synth_pendulum_peak_corner_speed_is_the_requested_speed() {
    for speed in [1.1, 3.9, 4.5, 16.0] {
        let seq = render_pendulum(&quiet(speed, PendulumMotion::Rotating)).unwrap();
        let measured = peak_corner_speed(&seq.truth);
        let rel = (measured - speed).abs() / speed;
        assert!(rel < 0.02, "speed {speed}: measured {measured}");
        assert!(rel < 1e-6, "speed {speed}: measured {measured} (exact by construction)");
    }
    // The axis-aligned variant, from the swing alone (no rendering needed).
    for speed in [1.1, 3.9, 4.5, 16.0] {
        let swing = PendulumSwing::new(speed, PendulumMotion::Translating, None).unwrap();
        let truth: Vec<TruthFrame> = (0..200)
            .map(|k| TruthFrame {
                frame: k,
                visible: true.into(),
                pose: None,
                params: Vec::new(),
                corners: swing.corners(k).to_vec(),
            })
            .collect();
        let measured = peak_corner_speed(&truth);
        assert!((measured - speed).abs() / speed < 1e-6, "translating {speed}: {measured}");
    }
}

#[test]
fn synth_pendulum_uses_the_natural_period_at_the_papers_speeds() {
    for speed in [1.1, 3.9, 4.5] {
        let swing = PendulumSwing::new(speed, PendulumMotion::Rotating, None).unwrap();
        assert!((swing.period_frames() - 122.0).abs() < 1e-9, "{speed}: {swing:?}");
        assert!(swing.amplitude_rad <= pendulum::MAX_AMPLITUDE_RAD);
    }
    let fast = PendulumSwing::new(16.0, PendulumMotion::Rotating, None).unwrap();
    assert!(fast.period_frames() < 122.0 && fast.amplitude_rad <= pendulum::MAX_AMPLITUDE_RAD);
    // Released from rest: frame 0 is the turning point.
    let swing = PendulumSwing::new(3.9, PendulumMotion::Rotating, None).unwrap();
    assert_eq!(swing.angle(0), swing.amplitude_rad);
}

#[test]
fn synth_pendulum_rectangle_stays_inside_the_frame() {
    let margin = 6.0;
    let speeds = [0.0, 0.5, 1.1, 2.0, 3.9, 4.5, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0, 24.0, 32.0];
    for motion in [PendulumMotion::Rotating, PendulumMotion::Translating] {
        for speed in speeds {
            for jump_at in [None, Some(1)] {
                let swing = PendulumSwing::new(speed, motion, jump_at).unwrap();
                for k in 0..400 {
                    for c in swing.corners(k) {
                        assert!(
                            c[0] >= margin
                                && c[0] <= WIDTH as f64 - 1.0 - margin
                                && c[1] >= margin
                                && c[1] <= HEIGHT as f64 - 1.0 - margin,
                            "{motion:?} speed {speed} jump {jump_at:?} frame {k}: corner {c:?}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn synth_pendulum_is_deterministic_per_seed() {
    let opts = |seed| PendulumOptions { frames: 4, seed, ..PendulumOptions::default() };
    let a = render_pendulum(&opts(5)).unwrap();
    let b = render_pendulum(&opts(5)).unwrap();
    let c = render_pendulum(&opts(6)).unwrap();
    assert_eq!(a.frames, b.frames);
    assert_eq!(a.truth, c.truth, "the motion does not depend on the seed");
    for k in 0..4 {
        let differing = a.frames[k].data().iter().zip(c.frames[k].data()).filter(|(p, q)| p != q);
        assert!(differing.count() > WIDTH * HEIGHT / 4, "frame {k}: seeds 5 and 6 too alike");
    }
    // Noise differs from frame to frame too (flat background, static object at speed 0).
    let still = render_pendulum(&PendulumOptions {
        frames: 2,
        speed: 0.0,
        background: Background::Flat,
        ..PendulumOptions::default()
    })
    .unwrap();
    assert_ne!(still.frames[0], still.frames[1]);
}

#[test]
fn synth_pendulum_noise_has_the_requested_sigma() {
    let seq = render_pendulum(&PendulumOptions {
        frames: 1,
        speed: 0.0,
        noise_sigma: 4.0,
        background: Background::Flat,
        ..PendulumOptions::default()
    })
    .unwrap();
    // Rows 0..60 are pure background (grey 100) above the rectangle.
    let values: Vec<f64> = (0..60).flat_map(|y| seq.frames[0].row(y).iter().map(|&v| f64::from(v))).collect();
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!((mean - 100.0).abs() < 0.1, "mean {mean}");
    // Rounding adds 1/12 grey² of variance.
    assert!((sd - (16.0f64 + 1.0 / 12.0).sqrt()).abs() < 0.1, "sd {sd}");
}

#[test]
fn synth_pendulum_jump_moves_the_truth() {
    let jump_at = 50;
    let seq = render_pendulum(&PendulumOptions {
        frames: 80,
        jump_at: Some(jump_at),
        ..quiet(3.9, PendulumMotion::Rotating)
    })
    .unwrap();
    let plain = render_pendulum(&PendulumOptions { frames: 80, ..quiet(3.9, PendulumMotion::Rotating) }).unwrap();
    for k in 0..80 {
        for (a, b) in seq.truth[k].corners.iter().zip(&plain.truth[k].corners) {
            let d = dist(*a, *b);
            if k < jump_at {
                assert_eq!(d, 0.0, "frame {k}");
            } else {
                assert!((d - JUMP_OFFSET_PX[0].hypot(JUMP_OFFSET_PX[1])).abs() < 1e-9, "frame {k}");
            }
        }
        assert!(seq.truth[k].visible.any());
    }
    let step = seq.truth[jump_at - 1].corners.iter().zip(&seq.truth[jump_at].corners);
    for (a, b) in step {
        assert!(dist(*a, *b) >= 60.0, "jump of {}", dist(*a, *b));
    }
    assert_ne!(seq.frames[jump_at], plain.frames[jump_at]);
}

#[test]
fn synth_pendulum_backgrounds_and_distractor_change_the_image() {
    let base = PendulumOptions { frames: 3, noise_sigma: 0.0, ..PendulumOptions::default() };
    let flat = render_pendulum(&PendulumOptions { background: Background::Flat, ..base.clone() }).unwrap();
    let textured = render_pendulum(&base).unwrap();
    let cluttered = render_pendulum(&PendulumOptions { background: Background::Cluttered, ..base.clone() }).unwrap();
    // Flat: the top-left corner region is exactly the background grey.
    assert!(flat.frames[0].row(0).iter().all(|&v| v == 100));
    assert_ne!(textured.frames[0], flat.frames[0]);
    assert_ne!(cluttered.frames[0], textured.frames[0]);
    assert_eq!(flat.truth, cluttered.truth);

    let with =
        render_pendulum(&PendulumOptions { frames: 3, distractor: true, background: Background::Flat, ..base.clone() })
            .unwrap();
    // The distractor crosses the band around row 30; frame 1 is mid-way through.
    let dark = |img: &GrayImage| (10..50).flat_map(|y| img.row(y).to_vec()).filter(|&v| v < 60).count();
    assert_eq!(dark(&flat.frames[1]), 0);
    assert!(dark(&with.frames[1]) > 200, "{}", dark(&with.frames[1]));
    assert_eq!(with.truth, flat.truth);
}

#[test]
fn synth_pendulum_rejects_bad_options() {
    let bad = [
        PendulumOptions { frames: 0, ..PendulumOptions::default() },
        PendulumOptions { speed: -1.0, ..PendulumOptions::default() },
        PendulumOptions { speed: f64::NAN, ..PendulumOptions::default() },
        PendulumOptions { speed: 1000.0, ..PendulumOptions::default() },
        PendulumOptions { noise_sigma: f64::INFINITY, ..PendulumOptions::default() },
        PendulumOptions { jump_at: Some(0), ..PendulumOptions::default() },
        PendulumOptions { jump_at: Some(200), ..PendulumOptions::default() },
    ];
    for opts in bad {
        assert!(matches!(render_pendulum(&opts), Err(Error::Parameter(_))), "{opts:?}");
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("synth-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> T {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// serde_json's default float parser may be one ulp off the written value.
fn assert_corners_close(a: &[[f64; 2]], b: &[[f64; 2]]) {
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(b) {
        assert!(dist(*p, *q) < 1e-9, "{p:?} vs {q:?}");
    }
}

#[test]
fn synth_generate_writes_a_sequence_folder() {
    let dir = scratch("generate");
    let extra = vec![("speed".to_string(), "4.5".to_string())];
    let seq = synth::generate("pendulum", &dir, Some(6), 3, &extra).unwrap();

    let camera: Camera = read_json(&dir.join("camera.json"));
    assert_eq!(camera, seq.camera);
    assert_eq!((camera.width, camera.height, camera.fx, camera.cx, camera.cy), (256, 242, 300.0, 127.5, 120.5));
    let model: Model = read_json(&dir.join("model.json"));
    assert_eq!((model.vertices.len(), model.edges.len(), model.faces.len()), (4, 4, 1));
    let init: InitState = read_json(&dir.join("init.json"));
    assert_corners_close(&init.corners, &seq.truth[0].corners);
    assert!(init.pose.is_none());
    let truth: Vec<TruthFrame> = std::fs::read_to_string(dir.join("truth.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(truth.len(), 6);
    for (read, made) in truth.iter().zip(&seq.truth) {
        assert_eq!((read.frame, &read.visible), (made.frame, &made.visible));
        assert_corners_close(&read.corners, &made.corners);
    }
    let meta: serde_json::Value = read_json(&dir.join("meta.json"));
    assert_eq!(meta["speed_px_per_frame"], 4.5);
    for k in 0..6 {
        let png = image::open(dir.join(format!("frames/{k:06}.png"))).unwrap();
        assert_eq!(png.color(), image::ColorType::L8);
        assert_eq!(png.to_luma8().into_raw(), seq.frames[k].data());
    }
    assert!(!dir.join("frames/000006.png").exists());

    // A non-empty folder is refused, and left alone.
    let err = synth::generate("pendulum", &dir, Some(2), 4, &[]).unwrap_err();
    assert!(matches!(err, Error::Input { .. }), "{err}");
    assert!(dir.join("frames/000005.png").exists());

    // An existing empty folder is fine.
    let empty = scratch("generate-empty");
    std::fs::create_dir_all(&empty).unwrap();
    synth::generate("pendulum", &empty, Some(1), 4, &[]).unwrap();
    assert!(empty.join("frames/000000.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&empty);
}

#[test]
fn synth_generate_validates_before_writing() {
    let dir = scratch("invalid");
    let err = synth::generate("teapot", &dir, None, 0, &[]).unwrap_err();
    match err {
        Error::Parameter(msg) => assert!(msg.contains("pendulum"), "{msg}"),
        other => panic!("{other}"),
    }
    assert!(synth::scene_names().contains(&"pendulum"));
    for (key, value) in
        [("speed", "-3"), ("speed", "fast"), ("background", "plaid"), ("colour", "red"), ("jump_at", "0")]
    {
        let extra = vec![(key.to_string(), value.to_string())];
        let err = synth::generate("pendulum", &dir, Some(5), 0, &extra).unwrap_err();
        assert!(matches!(err, Error::Parameter(_)), "{key}={value}: {err}");
    }
    let err = synth::generate("pendulum", &dir, Some(0), 0, &[]).unwrap_err();
    assert!(matches!(err, Error::Parameter(_)), "{err}");
    assert!(!dir.exists(), "nothing may be written for invalid arguments");
}

fn grey_frame(w: usize, h: usize, v: u8) -> GrayImage {
    GrayImage::from_vec(w, h, vec![v; w * h]).unwrap()
}

fn count_colour(img: &image::RgbImage, colour: [u8; 3]) -> usize {
    img.pixels().filter(|p| p.0 == colour).count()
}

#[test]
fn overlay_draws_yellow_when_tracking_and_red_when_lost() {
    let frame = grey_frame(32, 24, 100);
    let corners = [[4.0, 4.0], [20.0, 4.0], [20.0, 16.0], [4.0, 16.0]];
    let edges = [[0, 1], [1, 2], [2, 3], [3, 0]];
    let tracking = draw_overlay(&frame, &corners, &edges, Status::Tracking, &[]);
    let lost = draw_overlay(&frame, &corners, &edges, Status::Lost, &[]);
    assert_eq!(tracking.dimensions(), (32, 24));
    // Axis-aligned edges on pixel centres are drawn at full strength: the 4
    // sides of a 17x13 box, plus 4 cross-arm pixels outside it at each corner.
    let full = 2 * 17 + 2 * 11 + 4 * 4;
    assert_eq!(count_colour(&tracking, overlay::TRACKING_COLOUR), full);
    assert_eq!(count_colour(&tracking, overlay::LOST_COLOUR), 0);
    assert_eq!(count_colour(&lost, overlay::LOST_COLOUR), full);
    assert_eq!(count_colour(&lost, overlay::TRACKING_COLOUR), 0);
    // The inside of the box is untouched grey.
    assert_eq!(tracking.get_pixel(12, 10).0, [100, 100, 100]);
}

#[test]
fn overlay_antialiases_lines_between_pixel_centres() {
    let frame = grey_frame(12, 8, 0);
    // A horizontal line at y = 3.25 splits 3/4 into row 3 and 1/4 into row 4
    // (column 4 is clear of the corner crosses at x = 1 and 7).
    let img = draw_overlay(&frame, &[[1.0, 3.25], [7.0, 3.25]], &[[0, 1]], Status::Lost, &[]);
    assert_eq!(img.get_pixel(4, 3).0, [191, 0, 0]);
    assert_eq!(img.get_pixel(4, 4).0, [64, 0, 0]);
    assert_eq!(img.get_pixel(4, 2).0, [0, 0, 0]);
}

#[test]
fn overlay_tints_labelled_pixels() {
    let frame = grey_frame(4, 4, 100);
    let img = draw_overlay(&frame, &[], &[], Status::Tracking, &[(1, 1), (99, 99)]);
    // 0.65 · 100 + 0.35 · (0, 255, 255).
    assert_eq!(img.get_pixel(1, 1).0, [65, 154, 154]);
    assert_eq!(img.get_pixel(2, 2).0, [100, 100, 100]);
}

#[test]
fn overlay_survives_corners_outside_and_nan() {
    let frame = grey_frame(16, 12, 50);
    let corners = [
        [f64::NAN, 3.0],
        [5.0, f64::INFINITY],
        [-1e300, 1e300],
        [-40.0, 6.0],
        [60.0, 6.0],
        [8.0, -1e9],
        [8.0, 1e9],
        [1e18, 1e18],
    ];
    let edges = [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 6], [6, 7], [7, 0], [0, 99], [99, 100]];
    let img = draw_overlay(&frame, &corners, &edges, Status::Tracking, &[(u32::MAX, 0)]);
    assert_eq!(img.dimensions(), (16, 12));
    // The clipped horizontal line (corners 3-4) and vertical line (5-6) cross the image.
    assert_eq!(img.get_pixel(0, 6).0, overlay::TRACKING_COLOUR);
    assert_eq!(img.get_pixel(15, 6).0, overlay::TRACKING_COLOUR);
    assert_eq!(img.get_pixel(8, 0).0, overlay::TRACKING_COLOUR);
    assert_eq!(img.get_pixel(8, 11).0, overlay::TRACKING_COLOUR);
    // An empty frame works too.
    let empty = draw_overlay(&grey_frame(0, 0, 0), &corners, &edges, Status::Lost, &[(0, 0)]);
    assert_eq!(empty.dimensions(), (0, 0));
}
