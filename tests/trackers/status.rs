//! Probe.
use pipetrack::backend::{CpuBackend, EarlyVision};
use pipetrack::io::formats::{FrameResult, Status};
use pipetrack::synth::SyntheticSequence;
use pipetrack::synth::pendulum::{PendulumOptions, render_pendulum};
use pipetrack::synth::target3dof::{Target3dofOptions, render_target3dof};
use pipetrack::track::{BlueParams, BlueTracker, MotionEdgeParams, MotionEdgeTracker, Tracker, FrameOutcome};

fn err(t: &[[f64; 2]], p: &[[f64; 2]]) -> f64 {
    t.iter().zip(p).map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1])).sum::<f64>() / t.len() as f64
}

fn run(seq: &SyntheticSequence, tracker: &mut dyn Tracker) -> Vec<(FrameOutcome, FrameResult)> {
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let mut out = Vec::new();
    let mut backend = CpuBackend::new();
    pipetrack::track::run::track_frames(tracker, &mut backend as &mut dyn EarlyVision, seq.frames.iter().cloned().map(Ok), size, |_, o, r| {
        out.push((o.clone(), r.clone()));
        Ok(())
    })
    .expect("track");
    out
}

fn dump(name: &str, seq: &SyntheticSequence, out: &[(FrameOutcome, FrameResult)]) {
    let mut s = String::new();
    for ((o, r), t) in out.iter().zip(&seq.truth) {
        let fitted = o.diagnostics.line_fitted.iter().filter(|&&b| b).count();
        s += &format!(
            "{} {} err {:.2} sup {:?} fit {}/{} reason {:?}\n",
            r.frame,
            if r.status == Status::Tracking { "T" } else { "L" },
            err(&t.corners, &r.corners),
            o.diagnostics.contour_support.map(|v| (v * 100.0).round()),
            fitted,
            o.diagnostics.line_fitted.len(),
            o.diagnostics.lost_reason
        );
    }
    std::fs::write(format!("/tmp/probe/{name}.txt"), s).unwrap();
}

#[test]
#[ignore]
fn probe_blue() {
    let speed: f64 = std::env::var("SPEED").unwrap().parse().unwrap();
    let occ: f64 = std::env::var("OCC").map(|v| v.parse().unwrap()).unwrap_or(0.0);
    let opts = Target3dofOptions { frames: 300, speed, occlude: occ, ..Default::default() };
    let seq = render_target3dof(&opts).unwrap();
    let mut t = BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), BlueParams::default()).unwrap();
    let out = run(&seq, &mut t);
    dump(&format!("blue_{speed}_{occ}"), &seq, &out);
}

#[test]
#[ignore]
fn probe_me() {
    let speed: f64 = std::env::var("SPEED").unwrap().parse().unwrap();
    let jump = std::env::var("JUMP").ok().map(|v| v.parse().unwrap());
    let opts = PendulumOptions { frames: 200, speed, noise_sigma: 2.0, jump_at: jump, ..Default::default() };
    let seq = render_pendulum(&opts).unwrap();
    let mut t = MotionEdgeTracker::new(seq.init.corners.clone(), seq.model.edges.clone(), MotionEdgeParams::default()).unwrap();
    let out = run(&seq, &mut t);
    dump(&format!("me_{speed}_{jump:?}"), &seq, &out);
}
