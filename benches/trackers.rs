//! The trackers' own time per frame on one thread, apart from early vision
//! (see `pipetrack::cli::tracker_bench`): median, mean and slowest frame,
//! each frame timed at its fastest of several replays.

use pipetrack::cli::tracker_bench::time_trackers;

/// Replays per tracker; a frame counts at its fastest.
const PASSES: usize = 15;

fn main() -> pipetrack::Result<()> {
    // `cargo bench --bench trackers -- blue` times only the trackers named;
    // cargo adds flags of its own (`--bench`).
    let names: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| pipetrack::Error::Parameter(format!("cannot build a one-thread pool: {e}")))?;
    let timings = pool.install(|| time_trackers(&names, PASSES))?;
    println!(
        "{:<12} {:<11} {:>8} {:>7} {:>8} {:>10} {:>9} {:>8}",
        "tracker", "scene", "size", "frames", "tracked", "median ms", "mean ms", "max ms"
    );
    for t in &timings {
        println!(
            "{:<12} {:<11} {:>8} {:>7} {:>8} {:>10.4} {:>9.4} {:>8.3}",
            t.tracker, t.scene, t.size, t.frames, t.tracked, t.median_ms, t.mean_ms, t.max_ms
        );
    }
    Ok(())
}
