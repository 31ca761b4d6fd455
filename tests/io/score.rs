//! Scoring (the `score` command) on hand-worked cases: every figure below
//! can be checked with pencil and paper.

use std::fs;
use std::path::PathBuf;

use pipetrack::Error;
use pipetrack::cli::score::{
    ErrorStats, MAX_CORNER_ERROR_PX, read_predictions, score, score_file, score_file_with, score_with,
};
use pipetrack::io::formats::{FrameResult, Status, TruthFrame};

const SQUARE: [[f64; 2]; 4] = [[10.0, 10.0], [20.0, 10.0], [20.0, 20.0], [10.0, 20.0]];

fn truth(frame: usize, visible: bool) -> TruthFrame {
    TruthFrame { frame, visible: visible.into(), pose: None, params: Vec::new(), corners: SQUARE.to_vec() }
}

/// A prediction at the square moved by `(dx, dy)`, with corner 2 moved a further `(0, extra)`.
fn pred(frame: usize, status: Status, dx: f64, dy: f64, extra: f64) -> FrameResult {
    let mut corners: Vec<[f64; 2]> = SQUARE.iter().map(|c| [c[0] + dx, c[1] + dy]).collect();
    corners[2][1] += extra;
    FrameResult { ms: 1.0, ..FrameResult::new(frame, status, corners) }
}

/// Six frames: errors 5 (every corner off by (3,4)), 0, 1 (one corner of
/// four off by 4), lost, truth invisible, 2.
fn run() -> (Vec<TruthFrame>, Vec<FrameResult>) {
    use Status::{Lost, Tracking};
    let truth = vec![truth(0, true), truth(1, true), truth(2, true), truth(3, true), truth(4, false), truth(5, true)];
    let preds = vec![
        pred(0, Tracking, 3.0, 4.0, 0.0),
        pred(1, Tracking, 0.0, 0.0, 0.0),
        pred(2, Tracking, 0.0, 0.0, 4.0),
        pred(3, Lost, 50.0, 50.0, 0.0),
        pred(4, Tracking, 9.0, 9.0, 0.0),
        pred(5, Tracking, 0.0, 2.0, 0.0),
    ];
    (truth, preds)
}

#[test]
fn score_hand_worked_run() {
    let (truth, preds) = run();
    let s = score(&truth, &preds).unwrap();
    assert_eq!(s.frames, 6);
    assert_eq!(s.tracked, 5);
    assert_eq!(s.first_lost, Some(3));
    assert_eq!(s.frame_errors, vec![(0, 5.0), (1, 0.0), (2, 1.0), (5, 2.0)]);
    // Scored errors 5, 0, 1, 2: mean 2, median (1 + 2) / 2, p95 = 4th of 4 (rank ⌈3.8⌉), max 5.
    assert_eq!(s.stats, Some(ErrorStats { mean: 2.0, median: 1.5, p95: 5.0, max: 5.0 }));
    // Corner 2: 5 + 0 + 4 + 2 over 4 frames; the others 5 + 0 + 0 + 2.
    assert_eq!(s.corner_errors, vec![Some(1.75), Some(1.75), Some(2.75), Some(1.75)]);
    let text = s.to_string();
    assert!(text.contains("mean corner error:   2.000 px"), "{text}");
    assert!(text.contains("p95 corner error:    5.000 px"), "{text}");
    assert!(text.contains("frames tracked:      5 of 6"), "{text}");
    assert!(text.ends_with("first lost frame:    3"), "{text}");
}

/// The run of [`run`]: errors 5, 0, 1, 2 on the scored frames, and frame 4
/// tracking while truth shows nothing. At 5 px only frame 4 is false
/// tracking (5 is not above 5); at 1.5 px frames 0, 4 and 5; at 0.5 px also 2.
#[test]
fn false_tracking_counts_tracking_frames_off_by_more_than_the_threshold() {
    let (truth, preds) = run();
    let s = score(&truth, &preds).unwrap();
    assert_eq!(s.false_tracking_px, 5.0);
    assert_eq!(s.false_tracking, vec![4]);
    assert_eq!(s.false_tracking_fraction_of_tracked(), 1.0 / 5.0);
    assert_eq!(s.false_tracking_fraction(), 1.0 / 6.0);
    let text = s.to_string();
    assert!(
        text.contains("false tracking:      1 (20.0 % of tracked, 16.7 % of all frames; tracking with error > 5 px"),
        "{text}"
    );
    assert!(text.contains("false tracking at:   4\n"), "{text}");
    let at_1_5 = score_with(&truth, &preds, 1.5).unwrap();
    assert_eq!(at_1_5.false_tracking, vec![0, 4, 5]);
    assert!(at_1_5.to_string().contains("false tracking at:   0, 4–5\n"), "{at_1_5}");
    assert_eq!(score_with(&truth, &preds, 0.5).unwrap().false_tracking, vec![0, 2, 4, 5]);
    // A lost frame is never false tracking, however far off (frame 3: 70 px).
    assert!(!score_with(&truth, &preds, 0.0).unwrap().false_tracking.contains(&3));
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(score_with(&truth, &preds, bad), Err(Error::Parameter(_))), "{bad}");
    }
    let text: String = preds.iter().map(|p| serde_json::to_string(p).unwrap() + "\n").collect();
    let file = TempFile::new("false.jsonl", &text);
    assert_eq!(score_file_with(&truth, &file.0, 1.5).unwrap().false_tracking, vec![0, 4, 5]);
}

#[test]
fn score_with_nothing_to_score_says_so() {
    let truth = vec![truth(0, true)];
    let s = score(&truth, &[pred(0, Status::Lost, 0.0, 0.0, 0.0)]).unwrap();
    assert_eq!(s.stats, None);
    assert!(s.corner_errors.is_empty());
    assert!(s.to_string().contains("n/a"));
    let s = score(&truth, &[pred(0, Status::Tracking, 0.0, 0.0, 0.0)]).unwrap();
    assert!(s.to_string().ends_with("first lost frame:    none"));
    assert!(!s.to_string().contains("false tracking at"), "{s}");
}

#[test]
fn per_vertex_visibility_scores_only_the_visible_corners() {
    use pipetrack::io::formats::Visibility;
    // Frame 0: corner 2 hidden and off by 100 px, the others off by 2: error 2.
    // Frame 1: corners 0 and 2 hidden, corner 1 off by 6, corners 3 exact: error 3.
    // Frame 2: nothing visible: not scored although tracking.
    let mut truth = vec![truth(0, true), truth(1, true), truth(2, true)];
    truth[0].visible = Visibility::Vertices(vec![true, true, false, true]);
    truth[1].visible = Visibility::Vertices(vec![false, true, false, true]);
    truth[2].visible = Visibility::Vertices(vec![false; 4]);
    let p0 = pred(0, Status::Tracking, 0.0, 2.0, 98.0);
    let mut p1 = pred(1, Status::Tracking, 0.0, 0.0, 0.0);
    p1.corners[1][0] += 6.0;
    p1.corners[0][0] += 50.0;
    let p2 = pred(2, Status::Tracking, 9.0, 9.0, 0.0);
    let s = score(&truth, &[p0, p1, p2]).unwrap();
    assert_eq!(s.frame_errors, vec![(0, 2.0), (1, 3.0)]);
    // Corner 0 seen once (2), corner 1 twice (2, 6), corner 2 never, corner 3 twice (2, 0).
    assert_eq!(s.corner_errors, vec![Some(2.0), Some(4.0), None, Some(1.0)]);

    let mut short = truth.clone();
    short[0].visible = Visibility::Vertices(vec![true, true]);
    let msg = score(
        &short,
        &[
            pred(0, Status::Tracking, 0.0, 0.0, 0.0),
            pred(1, Status::Lost, 0.0, 0.0, 0.0),
            pred(2, Status::Lost, 0.0, 0.0, 0.0),
        ],
    )
    .unwrap_err()
    .to_string();
    assert!(msg.contains("frame 0: truth.jsonl has 2 visibility flags for 4 corners"), "{msg}");
}

#[test]
fn error_stats_percentiles() {
    let values: Vec<f64> = (1..=20).map(f64::from).collect();
    let s = ErrorStats::of(&values).unwrap();
    // Median of 1..20 is 10.5; p95 nearest rank is the 19th value.
    assert_eq!((s.mean, s.median, s.p95, s.max), (10.5, 10.5, 19.0, 20.0));
    let one = ErrorStats::of(&[3.0]).unwrap();
    assert_eq!((one.median, one.p95), (3.0, 3.0));
    assert_eq!(ErrorStats::of(&[]), None);
}

#[test]
fn mismatched_frames_are_errors() {
    let (truth, preds) = run();
    let msg = score(&truth, &preds[..4]).unwrap_err().to_string();
    assert!(msg.contains("4 frames (frames 0 to 3) but truth.jsonl has 6 (frames 0 to 5)"), "{msg}");
    let mut shifted = preds.clone();
    shifted[5].frame = 6;
    assert!(score(&truth, &shifted).unwrap_err().to_string().contains("frame 6 where truth.jsonl has frame 5"));
    let mut short = preds.clone();
    short[1].corners.pop();
    assert!(score(&truth, &short).unwrap_err().to_string().contains("frame 1: 3 corners but truth.jsonl has 4"));
    // Joint values are compared one to one: a count that differs is an error.
    let mut jointed = truth.clone();
    jointed.iter_mut().for_each(|t| t.params = vec![0.5]);
    let mut extra = preds.clone();
    extra.iter_mut().for_each(|p| p.params = Some(vec![0.5]));
    assert!(score(&jointed, &extra).is_ok());
    extra[2].params = Some(vec![0.5, 0.1]);
    let msg = score(&jointed, &extra).unwrap_err().to_string();
    assert!(msg.contains("frame 2: 2 joint values (\"params\") but truth.jsonl has 1"), "{msg}");
}

struct TempFile(PathBuf);

impl TempFile {
    fn new(name: &str, text: &str) -> Self {
        let p = std::env::temp_dir().join(format!("pipetrack-score-{}-{name}", std::process::id()));
        fs::write(&p, text).unwrap();
        TempFile(p)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = fs::remove_file(&self.0);
    }
}

fn input_message<T: std::fmt::Debug>(r: pipetrack::Result<T>, file: &TempFile) -> String {
    match r {
        Err(Error::Input { path, message }) => {
            assert_eq!(path, file.0);
            message
        }
        other => panic!("expected an input error, got {other:?}"),
    }
}

#[test]
fn predictions_file_round_trip_and_errors() {
    let (truth, preds) = run();
    let text: String = preds.iter().map(|p| serde_json::to_string(p).unwrap() + "\n").collect();
    let file = TempFile::new("good.jsonl", &text);
    assert_eq!(read_predictions(&file.0).unwrap(), preds);
    assert_eq!(score_file(&truth, &file.0).unwrap(), score(&truth, &preds).unwrap());

    let first_four: String = text.lines().take(4).map(|l| format!("{l}\n")).collect();
    let short = TempFile::new("short.jsonl", &first_four);
    assert!(input_message(score_file(&truth, &short.0), &short).starts_with("4 frames"));

    let bad = TempFile::new("bad.jsonl", &format!("{first_four}{{\"frame\":4,\"status\":\"sleeping\"}}\n"));
    let msg = input_message(read_predictions(&bad.0), &bad);
    assert!(msg.starts_with("line 5: wrong content at column"), "{msg}");

    let order = TempFile::new("order.jsonl", &format!("{first_four}{}", text.lines().next().unwrap()));
    assert!(input_message(read_predictions(&order.0), &order).starts_with("line 5: frame 0 after frame 3"));

    let no_corners =
        TempFile::new("nocorners.jsonl", "{\"frame\":0,\"status\":\"tracking\",\"corners\":[],\"ms\":1}\n");
    assert!(input_message(read_predictions(&no_corners.0), &no_corners).contains("no corners"));

    let empty = TempFile::new("empty.jsonl", "");
    assert!(input_message(read_predictions(&empty.0), &empty).starts_with("empty file"));
}

/// Pose errors, hand-worked: frame 0 off by 3 mm along x and 4 mm along y
/// (5 mm) and turned 2° about z, frame 1 exact; joint values 1° and 3° off.
#[test]
fn pose_errors_compare_translation_rotation_and_joints() {
    use pipetrack::io::formats::Pose;
    let pose = |r: [f64; 3], t: [f64; 3]| Some(Pose { rotation: r, translation: t });
    let mut truth = vec![truth(0, true), truth(1, true)];
    let mut preds = vec![pred(0, Status::Tracking, 0.0, 0.0, 0.0), pred(1, Status::Tracking, 0.0, 0.0, 0.0)];
    for t in &mut truth {
        t.pose = pose([0.0, 0.0, 0.3], [0.1, 0.0, 1.0]);
        t.params = vec![0.5];
    }
    preds[0].pose = pose([0.0, 0.0, 0.3 + 2f64.to_radians()], [0.103, 0.004, 1.0]);
    preds[0].params = Some(vec![0.5 + 1f64.to_radians()]);
    preds[1].pose = truth[1].pose;
    preds[1].params = Some(vec![0.5 - 3f64.to_radians()]);
    let e = score(&truth, &preds).unwrap().pose_errors.expect("poses on both sides");
    assert_eq!(e.frames, 2);
    assert!((e.translation_m[0] - 0.0025).abs() < 1e-12 && (e.translation_m[1] - 0.005).abs() < 1e-12, "{e:?}");
    assert!((e.rotation_deg[0] - 1.0).abs() < 1e-9 && (e.rotation_deg[1] - 2.0).abs() < 1e-9, "{e:?}");
    let [mean, max] = e.joint_deg.unwrap();
    assert!((mean - 2.0).abs() < 1e-9 && (max - 3.0).abs() < 1e-9, "{mean} {max}");
    let text = score(&truth, &preds).unwrap().to_string();
    assert!(text.contains("pose error:          translation 2.50 mm mean, 5.00 mm max"), "{text}");
    // Without poses, no pose figures.
    assert!(score(&run().0, &run().1).unwrap().pose_errors.is_none());
}

/// A corner far beyond any image (each coordinate finite, their distance
/// from the truth not) counts as `MAX_CORNER_ERROR_PX` off: the frame is
/// false tracking and every figure stays finite.
#[test]
fn a_corner_too_far_to_measure_counts_as_the_largest_error() {
    let truth = vec![truth(0, true), truth(1, true)];
    let mut far = pred(1, Status::Tracking, 0.0, 0.0, 0.0);
    far.corners[3] = [1e308, -1e308];
    let preds = [pred(0, Status::Tracking, 0.0, 0.0, 0.0), far];
    let text: String = preds.iter().map(|p| serde_json::to_string(p).unwrap() + "\n").collect();
    let file = TempFile::new("far.jsonl", &text);
    let s = score_file(&truth, &file.0).expect("scored");
    assert_eq!(s.frame_errors, vec![(0, 0.0), (1, MAX_CORNER_ERROR_PX / 4.0)]);
    assert_eq!(s.false_tracking, vec![1]);
    assert!(s.stats.is_some_and(|st| st.mean.is_finite() && st.max == MAX_CORNER_ERROR_PX / 4.0));
    // The summary says which frames were counted so, and only those.
    assert_eq!(s.capped_frames, vec![1]);
    let text = s.to_string();
    assert!(text.contains("corners too far:     a corner over 1e9 px off counted as 1e9 px at 1\n"), "{text}");
    let near = score(
        &truth,
        &preds[..1].iter().cloned().chain([pred(1, Status::Tracking, 0.0, 0.0, 0.0)]).collect::<Vec<_>>(),
    );
    assert!(!near.unwrap().to_string().contains("too far"));
}
