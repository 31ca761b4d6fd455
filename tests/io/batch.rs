//! The `batch` command as a user runs it: complete outputs skipped and a
//! stopped run finished, a bad sequence among good ones, shards that
//! partition a manifest, the Slurm and Kubernetes examples, manifest errors.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::pipetrack;

fn text(out: &Output) -> (String, String) {
    (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Pendulum sequences `s0 .. s{n-1}` of a few frames under `root`, and a
/// manifest listing them (motion-edge from `--tracker`).
fn sequences(root: &Path, n: usize) -> PathBuf {
    let mut manifest = String::from("# sequences of the batch tests\n\n");
    for i in 0..n {
        let seq = root.join(format!("s{i}"));
        let frames = (4 + i % 3).to_string();
        let out =
            pipetrack(&["synth", "pendulum", seq.to_str().unwrap(), "--frames", &frames, "--seed", &i.to_string()]);
        assert!(out.status.success(), "synth: {}", text(&out).1);
        manifest.push_str(&format!("s{i}\n"));
    }
    let path = root.join("manifest.txt");
    std::fs::write(&path, manifest).unwrap();
    path
}

fn batch_cpu(manifest: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args =
        vec!["batch", manifest.to_str().unwrap(), "--out", out.to_str().unwrap(), "--tracker", "motion-edge"];
    args.extend_from_slice(&["--backend", "cpu", "--jobs", "2"]);
    args.extend_from_slice(extra);
    pipetrack(&args)
}

/// `summary.jsonl`: every line valid JSON, by name.
fn summary(out: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(out.join("summary.jsonl")).unwrap();
    text.lines().map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l}: {e}"))).collect()
}

fn status_of(lines: &[serde_json::Value], name: &str) -> String {
    let matching: Vec<_> = lines.iter().filter(|l| l["name"] == name).collect();
    assert_eq!(matching.len(), 1, "one summary line for {name}: {lines:?}");
    matching[0]["status"].as_str().unwrap().to_string()
}

fn line_count(path: &Path) -> usize {
    std::fs::read_to_string(path).unwrap().lines().count()
}

#[test]
fn complete_outputs_are_skipped_and_a_stopped_run_is_finished() {
    let root = crate::common::scratch("batch", "restart");
    let manifest = sequences(&root, 4);
    let out = root.join("out");
    let first = batch_cpu(&manifest, &out, &[]);
    let (_, stderr) = text(&first);
    assert!(first.status.success(), "{stderr}");
    // stderr is not a terminal here: no progress bar, only the closing line.
    assert!(!stderr.contains('\r') && stderr.lines().all(|l| l.starts_with("pipetrack: ")), "{stderr:?}");
    assert!(stderr.contains("4 sequences tracked, 0 skipped, 0 failed"), "{stderr}");
    let lines = summary(&out);
    assert_eq!(lines.len(), 4);
    for (i, l) in lines.iter().enumerate() {
        assert_eq!(l["name"], format!("s{i}"), "manifest order");
        assert_eq!(l["status"], "tracked");
        assert_eq!(l["frames"], 4 + i % 3);
        assert!(l["mean_px"].as_f64().is_some_and(|e| e < 1.0), "error figures from truth.jsonl: {l}");
    }
    let kept = std::fs::metadata(out.join("s0.jsonl")).unwrap().modified().unwrap();

    // What a run stopped part-way leaves: a missing output, a partial file,
    // and (from some other run) an output that does not match its sequence.
    std::fs::remove_file(out.join("s1.jsonl")).unwrap();
    let stale = out.join("s1.jsonl.partial-4294967295-0");
    std::fs::write(&stale, "{\"frame\":0").unwrap();
    let long_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(60);
    std::fs::File::options().write(true).open(&stale).unwrap().set_modified(long_ago).unwrap();
    let s2 = std::fs::read_to_string(out.join("s2.jsonl")).unwrap();
    std::fs::write(out.join("s2.jsonl"), s2.lines().next().unwrap().to_string() + "\n").unwrap();

    let again = batch_cpu(&manifest, &out, &[]);
    let (stdout, stderr) = text(&again);
    assert!(again.status.success(), "{stderr}");
    let lines = summary(&out);
    assert_eq!(lines.len(), 4, "no duplicated summary lines: {lines:?}");
    assert_eq!(status_of(&lines, "s0"), "skipped");
    assert_eq!(status_of(&lines, "s1"), "tracked");
    assert_eq!(status_of(&lines, "s2"), "tracked");
    assert_eq!(status_of(&lines, "s3"), "skipped");
    assert!(lines[0]["fps"].as_f64().is_some(), "a skipped line keeps its run's fps: {}", lines[0]);
    assert_eq!(std::fs::metadata(out.join("s0.jsonl")).unwrap().modified().unwrap(), kept, "s0 not rewritten");
    for i in 0..4 {
        assert_eq!(line_count(&out.join(format!("s{i}.jsonl"))), 4 + i % 3);
    }
    assert!(!stale.exists(), "the killed run's partial file is removed");
    assert!(crate::common::partials(&out, "s1.jsonl").is_empty());
    assert!(stdout.contains("| s0 | motion-edge | skipped |"), "{stdout}");
    assert!(stdout.contains("| s1 | motion-edge | tracked |"), "{stdout}");

    // Nothing left to do: everything skipped, the summary unchanged but for statuses.
    let third = batch_cpu(&manifest, &out, &[]);
    assert!(third.status.success());
    let lines = summary(&out);
    assert!((0..4).all(|i| status_of(&lines, &format!("s{i}")) == "skipped"), "{lines:?}");
}

#[test]
fn a_bad_sequence_is_reported_and_the_others_finish() {
    let root = crate::common::scratch("batch", "bad");
    let manifest = sequences(&root, 4);
    // s1 fails while tracked, s2 before: the first failure named is s1's.
    std::fs::write(root.join("s1/frames/000002.png"), "not a png").unwrap();
    std::fs::write(root.join("s2/camera.json"), "{\"width\": 64,").unwrap();
    // s2's line ends in a slash: its failure still names its folder once.
    let with_missing = std::fs::read_to_string(&manifest).unwrap().replace("s2\n", "s2/\n") + "nowhere\n";
    std::fs::write(&manifest, with_missing).unwrap();
    let out = root.join("out");
    let run = batch_cpu(&manifest, &out, &[]);
    let (stdout, stderr) = text(&run);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let last = stderr.lines().last().unwrap();
    assert!(last.starts_with("pipetrack: 3 of 5 sequences failed") && last.contains("000002.png"), "{last}");
    let lines = summary(&out);
    assert_eq!(lines.len(), 5);
    for (name, needle) in [("s1", "000002.png"), ("s2", "camera.json"), ("nowhere", "no such folder")] {
        assert_eq!(status_of(&lines, name), "failed");
        let l = lines.iter().find(|l| l["name"] == name).unwrap();
        assert!(l["error"].as_str().unwrap().contains(needle), "{l}");
        assert!(!out.join(format!("{name}.jsonl")).exists(), "no output for {name}");
        assert!(crate::common::partials(&out, &format!("{name}.jsonl")).is_empty(), "no partial output for {name}");
        // One line names the failure, its folder once.
        let dir = root.join(name).display().to_string();
        let said = |l: &&str| l.starts_with(&format!("pipetrack: {dir}")) && l.matches(&dir).count() == 1;
        assert_eq!(stderr.lines().filter(said).count(), 1, "{stderr}");
        assert!(stdout.contains(&format!("| {name} | motion-edge | failed |")), "{stdout}");
    }
    for name in ["s0", "s3"] {
        assert_eq!(status_of(&lines, name), "tracked");
        assert!(out.join(format!("{name}.jsonl")).is_file());
    }

    // Mended, s2 is tracked on the next run; s1 still fails.
    std::fs::copy(root.join("s0/camera.json"), root.join("s2/camera.json")).unwrap();
    let run = batch_cpu(&manifest, &out, &[]);
    assert_eq!(run.status.code(), Some(2));
    let lines = summary(&out);
    assert_eq!(status_of(&lines, "s2"), "tracked");
    assert_eq!(status_of(&lines, "s1"), "failed");
}

/// An output is skipped only while the manifest gives its sequence the
/// tracker and the config text that made it (`<name>.run.json`); after a
/// change of either, or with that record gone, the sequence is tracked
/// again.
#[test]
fn an_output_of_another_tracker_or_config_is_tracked_again() {
    let root = crate::common::scratch("batch", "record");
    let manifest = sequences(&root, 2);
    let out = root.join("out");
    let run = |first: &str| {
        std::fs::write(&manifest, format!("{first}\ns1\n")).unwrap();
        let run = batch_cpu(&manifest, &out, &[]);
        let lines = summary(&out);
        (run, status_of(&lines, "s0"), status_of(&lines, "s1"))
    };
    let (first, s0, s1) = run("s0");
    assert!(first.status.success(), "{}", text(&first).1);
    assert_eq!((s0.as_str(), s1.as_str()), ("tracked", "tracked"));
    assert!(out.join("s0.run.json").is_file(), "the record beside the output");

    let config = root.join("smooth.toml");
    std::fs::write(&config, "[motion-edge]\nsigma = 1.5\n").unwrap();
    assert_eq!(run("s0 motion-edge smooth.toml").1, "tracked", "a config given");
    let (again, s0, s1) = run("s0 motion-edge smooth.toml");
    assert!(again.status.success());
    assert_eq!((s0.as_str(), s1.as_str()), ("skipped", "skipped"), "the same config");
    std::fs::write(&config, "[motion-edge]\nsigma = 2.0\n").unwrap();
    assert_eq!(run("s0 motion-edge smooth.toml").1, "tracked", "the config's text changed");

    // Another tracker: lowe refuses the pendulum's model in pixels, so the
    // old output is not reported as lowe's, and after it the record is gone.
    let (other, s0, _) = run("s0 lowe");
    assert_eq!(other.status.code(), Some(2));
    assert_eq!(s0, "failed");
    assert!(text(&other).1.contains("model.json"), "{}", text(&other).1);
    assert!(!out.join("s0.run.json").exists(), "no record for an output lowe did not write");
    assert_eq!(run("s0 motion-edge smooth.toml").1, "tracked", "back to motion-edge");

    // The record gone (a run stopped between the output and its record).
    std::fs::remove_file(out.join("s1.run.json")).unwrap();
    assert_eq!(run("s0 motion-edge smooth.toml").2, "tracked", "an output without its record");
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("s0.run.json")).unwrap()).unwrap();
    assert_eq!(record["tracker"], "motion-edge");
    assert_eq!(record["config"], "[motion-edge]\nsigma = 2.0\n");

    // The config gone: the sequence fails naming it, and leaves no record.
    std::fs::remove_file(&config).unwrap();
    let (gone, s0, _) = run("s0 motion-edge smooth.toml");
    assert_eq!(gone.status.code(), Some(2));
    assert_eq!(s0, "failed");
    assert!(text(&gone).1.contains("smooth.toml"), "{}", text(&gone).1);
    assert!(!out.join("s0.run.json").exists());
}

/// The names `--list` prints for `--shard I/N` with the binary's own parser.
fn listed(args: &[String]) -> Vec<String> {
    let args: Vec<&str> = args.iter().map(String::as_str).chain(["--list"]).collect();
    let out = pipetrack(&args);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{args:?}: {stderr}");
    stdout.lines().map(|l| l.split('\t').next().unwrap().to_string()).collect()
}

/// Every shard's list, checked to partition `names` exactly, each shard
/// taking positions I, I+N, … in manifest order.
fn check_partition(names: &[String], shards: &[Vec<String>]) {
    let n = shards.len();
    for (i, shard) in shards.iter().enumerate() {
        let want: Vec<String> = names.iter().skip(i).step_by(n).cloned().collect();
        assert_eq!(shard, &want, "shard {i}/{n}");
    }
    let mut all: Vec<String> = shards.concat();
    all.sort();
    let mut want = names.to_vec();
    want.sort();
    assert_eq!(all, want, "{n} shards cover every sequence once");
}

#[test]
fn shards_partition_a_manifest() {
    let root = crate::common::scratch("batch", "shards");
    let names: Vec<String> = (0..11).map(|i| format!("seq-{i:02}")).collect();
    let manifest = root.join("manifest.txt");
    std::fs::write(&manifest, names.iter().map(|n| format!("{n} motion-edge\n")).collect::<String>()).unwrap();
    for n in 1..=5 {
        let shards: Vec<Vec<String>> = (0..n)
            .map(|i| {
                let args = ["batch", manifest.to_str().unwrap(), "--out", "unused", "--shard", &format!("{i}/{n}")];
                listed(&args.map(String::from))
            })
            .collect();
        check_partition(&names, &shards);
    }
    let out = pipetrack(&["batch", manifest.to_str().unwrap(), "--out", "unused", "--shard", "3/3"]);
    assert_eq!(out.status.code(), Some(2), "I must be below N");
}

fn example(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/batch").join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `examples/batch/slurm.sh` run as every task of its array would run it,
/// all at once: each task tracks its shard into the shared output folder,
/// together they track the whole manifest once, and the summary has every
/// task's lines.
#[test]
fn slurm_example_splits_a_manifest_across_its_array() {
    let script = example("slurm.sh");
    assert!(script.contains("--shard \"$SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT\""), "{script}");
    let array = script.lines().find_map(|l| l.strip_prefix("#SBATCH --array=0-")).expect("an #SBATCH --array line");
    let tasks: usize = array.trim().parse::<usize>().unwrap() + 1;
    let root = crate::common::scratch("batch", "slurm");
    let manifest = sequences(&root, 6);
    let out = root.join("tracked");
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_pipetrack")).parent().unwrap();
    let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default());
    let script_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/batch/slurm.sh");
    let mut tracked = BTreeSet::new();
    let runs: Vec<_> = (0..tasks)
        .map(|task| {
            Command::new("bash")
                .arg(&script_path)
                .args(["--tracker", "motion-edge", "--backend", "cpu"])
                .env("PATH", &path)
                .env("SLURM_ARRAY_TASK_ID", task.to_string())
                .env("SLURM_ARRAY_TASK_COUNT", tasks.to_string())
                .env("MANIFEST", &manifest)
                .env("OUT", &out)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for (task, child) in runs.into_iter().enumerate() {
        let run = child.wait_with_output().unwrap();
        let (stdout, stderr) = text(&run);
        assert!(run.status.success(), "task {task}: {stderr}");
        let rows: Vec<&str> = stdout.lines().filter(|l| l.contains("| tracked |")).collect();
        let want: Vec<usize> = (task..6).step_by(tasks).collect();
        assert_eq!(rows.len(), want.len(), "task {task}: {stdout}");
        for i in want {
            assert!(tracked.insert(i), "s{i} tracked twice");
        }
    }
    assert_eq!(tracked, (0..6).collect::<BTreeSet<_>>());
    let lines = summary(&out);
    assert_eq!(lines.len(), 6, "every task merged its lines: {lines:?}");
    assert!((0..6).all(|i| status_of(&lines, &format!("s{i}")) == "tracked"));
}

/// `examples/batch/indexed-job.yaml`: its container arguments, with the
/// completion index put in as Kubernetes does, parse with the binary's own
/// parser, and the `completions` pods take shards that partition a manifest.
#[test]
fn indexed_job_example_splits_a_manifest_across_its_pods() {
    let yaml = example("indexed-job.yaml");
    let field = |key: &str| {
        yaml.lines().find_map(|l| l.trim().strip_prefix(key)).unwrap_or_else(|| panic!("no {key} in the example"))
    };
    let completions: usize = field("completions:").trim().parse().unwrap();
    assert_eq!(field("completionMode:").trim(), "Indexed");
    assert_eq!(field("command:").trim(), "[\"pipetrack\"]");
    let args: Vec<String> = serde_json::from_str(field("args:").trim()).expect("args as a flow list");
    let shard = args.iter().position(|a| a == "--shard").expect("--shard") + 1;
    assert_eq!(args[shard], format!("$(JOB_COMPLETION_INDEX)/{completions}"), "N = completions");

    let root = crate::common::scratch("batch", "k8s");
    let names: Vec<String> = (0..10).map(|i| format!("clip{i}")).collect();
    let manifest = root.join("manifest.txt");
    std::fs::write(&manifest, names.iter().map(|n| format!("{n} blue\n")).collect::<String>()).unwrap();
    let shards: Vec<Vec<String>> = (0..completions)
        .map(|index| {
            let mut pod: Vec<String> = std::iter::once("pipetrack".to_string())
                .chain(args.iter().map(|a| a.replace("$(JOB_COMPLETION_INDEX)", &index.to_string())))
                .collect();
            assert_eq!(pod[1], "batch");
            pod[2] = manifest.to_str().unwrap().to_string();
            listed(&pod[1..])
        })
        .collect();
    check_partition(&names, &shards);
}

#[test]
fn manifest_errors_name_the_manifest_and_line() {
    let root = crate::common::scratch("batch", "manifest");
    let manifest = root.join("manifest.txt");
    let out = root.join("out");
    for (content, needles) in [
        ("a motion-edge\nb lowe-ish\n", vec!["manifest.txt", "line 2", "unknown tracker \"lowe-ish\""]),
        ("x/seq blue\n# c\ny/seq blue\n", vec!["manifest.txt", "line 3", "\"seq\"", "line 1"]),
        ("seq\n", vec!["manifest.txt", "line 1", "no tracker"]),
        ("# nothing\n\n", vec!["manifest.txt", "lists no sequences"]),
        ("a blue cfg.toml extra\n", vec!["line 1", "4 fields"]),
        ("summary blue\n", vec!["line 1", "\"summary\""]),
        ("\"sp ace\" blue\n", vec!["line 1", "unknown tracker \"ace\\\"\"", "without quoting"]),
        (
            "a lowe-ish\n",
            vec!["line 1", "unknown tracker \"lowe-ish\"; known: motion-edge, blue, condensation, lowe\n"],
        ),
        ("\"my big seq\" lowe\n", vec!["line 1", "got 4 fields", "without quoting"]),
    ] {
        std::fs::write(&manifest, content).unwrap();
        let run = pipetrack(&["batch", manifest.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        let (_, stderr) = text(&run);
        assert_eq!(run.status.code(), Some(2), "{content:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        for n in &needles {
            assert!(stderr.contains(n), "{n:?} missing from {stderr}");
        }
        assert!(!out.exists(), "nothing written for a bad manifest");
    }
}

/// A folder as the manifest: its sub-folders, sorted, the output folder left out.
#[test]
fn a_folder_of_sequences_is_a_manifest() {
    let root = crate::common::scratch("batch", "folder");
    sequences(&root, 3);
    std::fs::remove_file(root.join("manifest.txt")).unwrap();
    let out = root.join("zz-out");
    let run = batch_cpu(&root, &out, &[]);
    assert!(run.status.success(), "{}", text(&run).1);
    let lines = summary(&out);
    let names: Vec<&str> = lines.iter().map(|l| l["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["s0", "s1", "s2"]);
    let again = batch_cpu(&root, &out, &[]);
    assert!(again.status.success(), "{}", text(&again).1);
    assert_eq!(summary(&out).len(), 3, "the output folder is not taken for a sequence");
}

/// One sequence folder given as the manifest is refused as such, not
/// searched for sequences (its `frames` folder taken for one).
#[test]
fn a_sequence_folder_as_the_manifest_is_refused() {
    let root = crate::common::scratch("batch", "one-sequence");
    sequences(&root, 1);
    let seq = root.join("s0");
    let out = root.join("out");
    for extra in [&[][..], &["--list"][..]] {
        let run = batch_cpu(&seq, &out, extra);
        let (stdout, stderr) = text(&run);
        assert_eq!(run.status.code(), Some(2), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        let line = stderr.lines().next().unwrap();
        assert!(line.contains(&seq.display().to_string()), "{line}");
        assert!(line.contains("is a sequence folder") && line.contains("give its parent folder"), "{line}");
        assert!(!line.contains("frames"), "{line}");
        assert!(stdout.is_empty() && !out.exists(), "nothing written");
    }
}

/// A closed stderr does not stop a batch from reporting a failed sequence
/// in its summary and its exit status.
#[test]
fn a_failed_sequence_with_stderr_closed_is_no_panic() {
    let root = crate::common::scratch("batch", "stderr-closed");
    let manifest = sequences(&root, 2);
    std::fs::write(root.join("s1/camera.json"), "{\"width\": 64,").unwrap();
    let out = root.join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(["batch", manifest.to_str().unwrap(), "--out", out.to_str().unwrap(), "--tracker", "motion-edge"])
        .args(["--backend", "cpu"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("binary runs");
    drop(child.stderr.take());
    let status = child.wait().expect("binary ends");
    assert_eq!(status.code(), Some(2), "a failed sequence: status 2, no panic (101)");
    assert_eq!(status_of(&summary(&out), "s1"), "failed");
    assert_eq!(status_of(&summary(&out), "s0"), "tracked");
}
