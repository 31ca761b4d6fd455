//! GPU/CPU parity of `shaders/compaction.wgsl` against its twin in
//! src/early/compaction.rs.
//!
//! Tolerance: none. Compaction only compares and copies, and the subsample
//! uses the same u32 integer arithmetic in both twins, so the lists must be
//! equal element for element (θ and magnitude bit for bit).
use crate::common;
use crate::per_size;

use pipetrack::early::compaction::{self, CompactionParams, MAX_CAP};
use pipetrack::early::{Feature, Window};
use pipetrack::image::FloatImage;
use pipetrack::testimage::natural;

/// The select images and thresholds of a `w`×`h` test: a 0/1 mask from
/// thresholding `natural`, and a gradient magnitude (|dx| + |dy| of forward
/// differences) with a threshold; plus θ = atan2(dy, dx) (0 where both are 0).
struct Inputs {
    mask: FloatImage,
    magnitude: FloatImage,
    theta: FloatImage,
}

/// Magnitude threshold: keeps roughly the edge pixels of `natural`.
const MAGNITUDE_THRESHOLD: f32 = 6.0;

fn inputs(w: usize, h: usize) -> Inputs {
    let img = natural(w, h, 5).to_f32();
    let mask = FloatImage::from_fn(w, h, |x, y| if img.get(x, y) > 128.0 { 1.0 } else { 0.0 });
    let d = |x: usize, y: usize| {
        let dx = img.get((x + 1).min(w - 1), y) - img.get(x, y);
        let dy = img.get(x, (y + 1).min(h - 1)) - img.get(x, y);
        (dx, dy)
    };
    let magnitude = FloatImage::from_fn(w, h, |x, y| {
        let (dx, dy) = d(x, y);
        dx.abs() + dy.abs()
    });
    let theta = FloatImage::from_fn(w, h, |x, y| {
        let (dx, dy) = d(x, y);
        if dx == 0.0 && dy == 0.0 { 0.0 } else { dy.atan2(dx) }
    });
    Inputs { mask, magnitude, theta }
}

/// Full, off-centre, partially outside, empty, one pixel, one column.
fn windows(w: usize, h: usize) -> Vec<(&'static str, Window)> {
    let (w, h) = (w as u32, h as u32);
    vec![
        ("full", Window::full(w as usize, h as usize)),
        ("offcentre", Window { x0: w / 5, y0: h / 3, x1: w / 5 + w / 2, y1: h / 3 + h / 3 + 1 }),
        ("outside", Window { x0: w / 2, y0: h / 2, x1: w + 50, y1: h + 40 }),
        ("empty", Window { x0: w / 2, y0: 0, x1: w / 2, y1: h }),
        ("pixel", Window { x0: w / 2, y0: h / 2, x1: w / 2 + 1, y1: h / 2 + 1 }),
        ("column", Window { x0: w / 3, y0: 0, x1: w / 3 + 1, y1: h }),
    ]
}

/// Lists equal, or a panic naming the first differing index.
fn assert_lists_equal(name: &str, cpu: &[Feature], gpu: &[Feature]) {
    if let Some(i) = cpu.iter().zip(gpu).position(|(c, g)| bytemuck::bytes_of(c) != bytemuck::bytes_of(g)) {
        panic!(
            "{name}: lists differ first at index {i}: cpu {:?} gpu {:?} (lengths {} and {})",
            cpu[i],
            gpu[i],
            cpu.len(),
            gpu.len()
        );
    }
    assert_eq!(
        cpu.len(),
        gpu.len(),
        "{name}: lengths differ (cpu {}, gpu {}); common prefix equal",
        cpu.len(),
        gpu.len()
    );
}

/// `sub` is a subsequence of `all` (same order).
fn is_ordered_subset(sub: &[Feature], all: &[Feature]) -> bool {
    let mut it = all.iter();
    sub.iter().all(|s| it.any(|a| a == s))
}

fn parity_compaction_windows_and_caps(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_compaction_windows_and_caps/{w}x{h}")) else { return };
    let inp = inputs(w, h);
    let selects = [("mask", &inp.mask, 0.5f32), ("magnitude", &inp.magnitude, MAGNITUDE_THRESHOLD)];
    for (sname, select, threshold) in selects {
        for (wname, window) in windows(w, h) {
            let uncapped = CompactionParams { window, threshold, cap: None, seed: 3 };
            let all = compaction::compaction(select, &inp.theta, &inp.magnitude, &uncapped).unwrap();
            let n = all.len() as u32;
            let name = format!("compaction/{w}x{h}/{sname}/{wname}");
            let gpu = compaction::compaction_gpu(ctx, select, &inp.theta, &inp.magnitude, &uncapped).unwrap();
            assert_lists_equal(&format!("{name}/uncapped"), &all, &gpu);
            if wname == "empty" {
                assert!(all.is_empty(), "{name}: empty window listed {n}");
            }

            for cap in [1500, (n + 10).min(MAX_CAP), 1] {
                let p = CompactionParams { cap: Some(cap), ..uncapped };
                let cpu = compaction::compaction(select, &inp.theta, &inp.magnitude, &p).unwrap();
                let gpu = compaction::compaction_gpu(ctx, select, &inp.theta, &inp.magnitude, &p).unwrap();
                let cname = format!("{name}/cap{cap}");
                assert_lists_equal(&cname, &cpu, &gpu);
                assert_eq!(cpu.len() as u32, n.min(cap), "{cname}: length");
                assert!(is_ordered_subset(&cpu, &all), "{cname}: not an ordered subset of the uncapped list");
                if cap >= n {
                    assert_eq!(cpu, all, "{cname}: cap ≥ n must return all");
                }
            }
        }
    }
}
per_size!(parity_compaction_windows_and_caps; w1280_h720 = (1280, 720));

#[test]
fn parity_compaction_cap_1500_is_exercised_and_seeds_differ() {
    let Some((ctx, _g)) = common::gpu("parity_compaction_cap_1500_is_exercised_and_seeds_differ") else { return };
    let (w, h) = (640, 480);
    let inp = inputs(w, h);
    let base = CompactionParams { window: Window::full(w, h), threshold: MAGNITUDE_THRESHOLD, cap: None, seed: 1 };
    let all = compaction::compaction(&inp.magnitude, &inp.theta, &inp.magnitude, &base).unwrap();
    assert!(all.len() > 1500, "test image too plain: {} pixels above threshold", all.len());
    let capped = |seed: u32| {
        let p = CompactionParams { cap: Some(1500), seed, ..base };
        let cpu = compaction::compaction(&inp.magnitude, &inp.theta, &inp.magnitude, &p).unwrap();
        let gpu = compaction::compaction_gpu(ctx, &inp.magnitude, &inp.theta, &inp.magnitude, &p).unwrap();
        assert_lists_equal(&format!("compaction/seed{seed}"), &cpu, &gpu);
        assert_eq!(cpu.len(), 1500);
        assert!(is_ordered_subset(&cpu, &all), "seed {seed}: not an ordered subset");
        cpu
    };
    let (a, b) = (capped(1), capped(2));
    let same = a.iter().zip(&b).filter(|(x, y)| x == y).count();
    assert!(same < a.len() / 2, "seeds 1 and 2 share {same} of {} points", a.len());
    // Spread over the window: the subsample reaches the first and last tenth of the rows listed.
    let (ymin, ymax) = (all[0].y, all[all.len() - 1].y);
    let span = ymax - ymin;
    assert!(a[0].y <= ymin + span / 10 && a[a.len() - 1].y >= ymax - span / 10, "subsample not spread over the rows");
}

/// The lists are the same whatever run of pixels each invocation reads
/// (`GpuContext::with_compaction_run`): the runs a CPU adapter and a GPU
/// get (32 and 8), one pixel, and a run that does not divide the rows.
#[test]
fn parity_compaction_every_run_length() {
    let Some((ctx, _g)) = common::gpu("parity_compaction_every_run_length") else { return };
    assert!(ctx.with_compaction_run(0).is_err() && ctx.with_compaction_run(33).is_err());
    for run in [1, 5, 8, 32] {
        let run_ctx = ctx.with_compaction_run(run).unwrap();
        assert_eq!(run_ctx.compaction_run(), run);
        for &(w, h) in common::PARITY_SIZES {
            let inp = inputs(w, h);
            for (wname, window) in windows(w, h) {
                for cap in [None, Some(1500), Some(1)] {
                    let p = CompactionParams { window, threshold: MAGNITUDE_THRESHOLD, cap, seed: 7 };
                    let cpu = compaction::compaction(&inp.magnitude, &inp.theta, &inp.magnitude, &p).unwrap();
                    let gpu =
                        compaction::compaction_gpu(&run_ctx, &inp.magnitude, &inp.theta, &inp.magnitude, &p).unwrap();
                    assert_lists_equal(&format!("compaction/run{run}/{w}x{h}/{wname}/cap{cap:?}"), &cpu, &gpu);
                }
            }
        }
    }
}
