//! Sharded studies: every study run as N shards in separate processes and merged writes
//! what the study run whole writes (durations aside); a Slurm array's environment names
//! the shard; a stopped shard keeps its runs; and `study merge` refuses a missing,
//! duplicated, foreign, unfinished or tampered shard, naming the file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rig_tools::study::all::STUDIES;
use rig_tools::study::shard::manifest::Manifest;

fn exe() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_study"))
}

fn fresh(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("study-shard-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs `study args…` with the environment `env` (and no Slurm or Kubernetes variables of
/// the test's own environment).
fn study(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(exe());
    c.args(args);
    for v in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_MIN",
        "SLURM_ARRAY_TASK_STEP",
        "SLURM_ARRAY_TASK_COUNT",
        "JOB_COMPLETION_INDEX",
        "STUDY_SHARD_COUNT",
    ] {
        c.env_remove(v);
    }
    c.envs(env.iter().copied());
    c.output().expect("the study binary runs")
}

fn ok(o: &Output) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        o.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

fn refused(o: &Output) -> String {
    assert!(
        !o.status.success(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `line` with every duration (a number followed by `s` or ` s`, then no letter) masked.
fn mask_durations(line: &str) -> String {
    let c: Vec<char> = line.chars().collect();
    let mut out = String::new();
    let mut i = 0;
    while i < c.len() {
        if c[i].is_ascii_digit() && (i == 0 || !c[i - 1].is_alphanumeric()) {
            let mut j = i;
            while j < c.len() && (c[j].is_ascii_digit() || c[j] == '.') {
                j += 1;
            }
            let k = if j < c.len() && c[j] == ' ' { j + 1 } else { j };
            let unit = k < c.len() && c[k] == 's';
            let ends = k + 1 >= c.len() || !c[k + 1].is_alphanumeric();
            if unit && ends {
                out.push_str("<t>");
                i = j;
                continue;
            }
            out.extend(&c[i..j]);
            i = j;
            continue;
        }
        out.push(c[i]);
        i += 1;
    }
    out
}

/// Every file under `dir` except its `shards/` folders, relative.
fn files(dir: &Path) -> Vec<PathBuf> {
    fn walk(base: &Path, d: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                if p.file_name().is_some_and(|n| n == "shards") {
                    continue;
                }
                walk(base, &p, out);
            } else {
                out.push(p.strip_prefix(base).unwrap().to_path_buf());
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, dir, &mut v);
    v.sort();
    v
}

/// The two folders hold the same files, byte for byte, text lines aside only in their
/// durations; returns how many files were compared.
fn assert_same_tree(whole: &Path, merged: &Path) -> usize {
    let a = files(whole);
    assert_eq!(a, files(merged), "the merge wrote other files");
    for f in &a {
        let x = std::fs::read(whole.join(f)).unwrap();
        let y = std::fs::read(merged.join(f)).unwrap();
        if x == y {
            continue;
        }
        let (Ok(x), Ok(y)) = (String::from_utf8(x), String::from_utf8(y)) else {
            panic!("{}: binary files differ", f.display());
        };
        let (lx, ly): (Vec<&str>, Vec<&str>) = (x.lines().collect(), y.lines().collect());
        assert_eq!(lx.len(), ly.len(), "{}: line counts differ", f.display());
        for (n, (p, q)) in lx.iter().zip(&ly).enumerate() {
            assert_eq!(
                mask_durations(p),
                mask_durations(q),
                "{}:{}: differs beyond its durations",
                f.display(),
                n + 1
            );
        }
    }
    a.len()
}

#[test]
fn durations_are_masked_and_nothing_else() {
    assert_eq!(
        mask_durations("total 2.8 s; 1.24 s of computation, **16.6 s**, 0.3s."),
        "total <t> s; <t> s of computation, **<t> s**, <t>s."
    );
    assert_eq!(
        mask_durations("54 runs of 12000 steps, tau_n = 40, 3 samples, 12 seeds, x2s"),
        "54 runs of 12000 steps, tau_n = 40, 3 samples, 12 seeds, x2s"
    );
}

#[test]
fn every_study_sharded_in_three_and_merged_writes_what_the_whole_run_writes() {
    let d = fresh("all");
    let out = d.join("out");
    ok(&study(
        &["all", "--quick", "--out", s(&out), "--shard", "none"],
        &[],
    ));
    let whole = d.join("whole");
    std::fs::rename(&out, &whole).unwrap();
    for i in 0..3 {
        let shard = format!("{i}/3");
        let line = ok(&study(
            &["all", "--quick", "--out", s(&out), "--shard", &shard],
            &[],
        ));
        assert!(
            line.contains(&format!("shard {shard} of every study")),
            "{line}"
        );
        assert!(
            !out.join("reproduction.md").exists(),
            "a shard wrote the report"
        );
    }
    // Each study was sharded: its runs are dealt to the three shards, none twice.
    for st in STUDIES {
        let shards = out.join(st.name).join("shards");
        let m: Vec<Manifest> = (0..3)
            .map(|i| Manifest::read(&shards.join(format!("{i}-of-3"))).unwrap())
            .collect();
        let total = m[0].runs_total.unwrap();
        assert!(total >= 3, "{}: {total} runs sharded", st.name);
        let counts: Vec<usize> = m.iter().map(|m| m.runs_recorded).collect();
        assert_eq!(counts.iter().sum::<usize>(), total, "{}", st.name);
        assert!(
            counts.iter().max().unwrap() - counts.iter().min().unwrap() <= 1,
            "{}: {counts:?}",
            st.name
        );
        assert!(m.iter().all(|m| m.complete && m.study == st.name));
    }
    ok(&study(&["merge", s(&out)], &[]));
    let n = assert_same_tree(&whole, &out);
    assert!(n > 6 * 3, "only {n} files");
}

/// `study forgetting --runs 10` (a few hundred milliseconds) as shards of two.
fn forgetting(out: &Path, shard: &str) -> Output {
    study(
        &[
            "forgetting",
            "--runs",
            "10",
            "--out",
            s(out),
            "--shard",
            shard,
        ],
        &[],
    )
}

#[test]
fn a_slurm_array_names_the_shard_and_a_stopped_shard_keeps_its_runs() {
    let d = fresh("slurm");
    let out = d.join("out");
    ok(&forgetting(&out, "none"));
    let whole = d.join("whole");
    std::fs::rename(&out, &whole).unwrap();
    // --array=1-3:2 → tasks 1 and 3 are shards 0 and 1 of 2.
    for id in ["1", "3"] {
        ok(&study(
            &["forgetting", "--runs", "10", "--out", s(&out)],
            &[
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ],
        ));
    }
    let shard0 = out.join("shards").join("0-of-2");
    assert!(
        out.join("shards")
            .join("1-of-2")
            .join("manifest.json")
            .is_file()
    );
    // Stop shard 0 halfway: keep half its log, the last kept line cut short.
    let log = shard0.join("runs.jsonl");
    let text = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines.len() >= 4, "{} runs", lines.len());
    let keep = lines.len() / 2;
    let mut cut = lines[..keep].join("\n");
    cut.push('\n');
    cut.push_str(&lines[keep][..lines[keep].len() / 2]);
    std::fs::write(&log, cut).unwrap();
    let mut m = Manifest::read(&shard0).unwrap();
    m.complete = false;
    m.write(&shard0).unwrap();
    let e = refused(&study(&["merge", s(&out)], &[]));
    assert!(e.contains("0-of-2") && e.contains("is not complete"), "{e}");
    let again = ok(&forgetting(&out, "0/2"));
    assert!(
        again.contains(&format!("({keep} from an earlier attempt)")),
        "{again}"
    );
    assert_eq!(
        std::fs::read_to_string(&log).unwrap().lines().count(),
        lines.len()
    );
    ok(&study(&["merge", s(&out)], &[]));
    assert_same_tree(&whole, &out);
}

#[test]
fn merge_refuses_missing_duplicated_foreign_and_tampered_shards() {
    let d = fresh("refuse");
    let out = d.join("out");
    ok(&forgetting(&out, "0/2"));
    ok(&forgetting(&out, "1/2"));
    let shards = out.join("shards");
    let (s0, s1) = (shards.join("0-of-2"), shards.join("1-of-2"));

    let e = refused(&study(&["merge", s(&s0)], &[]));
    assert!(e.contains("1 of 2 shards missing: 1-of-2"), "{e}");

    let copy = d.join("copy").join("0-of-2");
    std::fs::create_dir_all(&copy).unwrap();
    for f in ["manifest.json", "runs.jsonl"] {
        std::fs::copy(s0.join(f), copy.join(f)).unwrap();
    }
    let e = refused(&study(&["merge", s(&out), s(&copy)], &[]));
    assert!(
        e.contains("shard 0/2 is given twice") && e.contains(s(&copy)),
        "{e}"
    );

    let other = d.join("other");
    ok(&study(
        &[
            "forgetting",
            "--runs",
            "12",
            "--out",
            s(&other),
            "--shard",
            "1/2",
        ],
        &[],
    ));
    let foreign = other.join("shards").join("1-of-2");
    let e = refused(&study(&["merge", s(&s0), s(&foreign)], &[]));
    assert!(
        e.contains("a shard of another run") && e.contains(s(&foreign.join("manifest.json"))),
        "{e}"
    );
    // The same folder cannot take a shard of other options either.
    let e = refused(&study(
        &[
            "forgetting",
            "--runs",
            "12",
            "--out",
            s(&out),
            "--shard",
            "1/2",
        ],
        &[],
    ));
    assert!(e.contains("holds shard 1/2 of another run"), "{e}");

    // A record whose item is not the study's.
    let log = s1.join("runs.jsonl");
    let text = std::fs::read_to_string(&log).unwrap();
    let key = text
        .split("\"key\":\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .unwrap()
        .to_string();
    std::fs::write(&log, text.replacen(&key, &"0".repeat(key.len()), 1)).unwrap();
    let e = refused(&study(&["merge", s(&out)], &[]));
    assert!(
        e.contains(s(&log)) && e.contains("recorded for another item"),
        "{e}"
    );

    let e = refused(&forgetting(&out, "2/2"));
    assert!(e.contains("--shard 2/2"), "{e}");
    let e = refused(&study(&["merge", s(&d.join("nothing-here"))], &[]));
    assert!(e.contains("nothing-here"), "{e}");
}

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn the_documented_slurm_script_runs_the_shards_that_merge_into_the_whole_study() {
    let d = fresh("sbatch");
    let out = d.join("out");
    ok(&forgetting(&out, "none"));
    let whole = d.join("whole");
    std::fs::rename(&out, &whole).unwrap();
    let script = root().join("docs/cluster/study-array.sbatch");
    for id in ["0", "1"] {
        let o = Command::new("bash")
            .arg(&script)
            .args(["forgetting", "--runs", "10"])
            .env("STUDY", exe())
            .env("OUT", &out)
            .env("SLURM_ARRAY_TASK_ID", id)
            .env("SLURM_ARRAY_TASK_MIN", "0")
            .env("SLURM_ARRAY_TASK_COUNT", "2")
            .env_remove("SLURM_ARRAY_TASK_STEP")
            .output()
            .unwrap();
        let line = ok(&o);
        assert!(
            line.contains(&format!("shard {id}/2 of study forgetting")),
            "{line}"
        );
    }
    ok(&study(&["merge", s(&out)], &[]));
    assert_same_tree(&whole, &out);
}

#[test]
fn the_documented_indexed_job_gives_its_shards_the_jobs_completions() {
    let yaml = std::fs::read_to_string(root().join("docs/cluster/study-indexed-job.yaml")).unwrap();
    let value_after = |key: &str| -> String {
        let i = yaml.find(key).unwrap_or_else(|| panic!("no {key}"));
        yaml[i + key.len()..]
            .lines()
            .next()
            .unwrap()
            .trim()
            .trim_matches('"')
            .to_string()
    };
    assert_eq!(value_after("completionMode:"), "Indexed");
    let completions = value_after("completions:");
    let i = yaml.find("name: STUDY_SHARD_COUNT").unwrap();
    let count = yaml[i..]
        .lines()
        .nth(1)
        .and_then(|l| l.trim().strip_prefix("value:"))
        .unwrap()
        .trim()
        .trim_matches('"')
        .to_string();
    assert_eq!(count, completions);
    let docker = std::fs::read_to_string(root().join("docs/cluster/Dockerfile")).unwrap();
    assert!(docker.contains("cargo build --release -p rig-tools --bin study"));
    assert!(docker.contains("COPY --from=build /src/scenarios /src/scenarios"));
}
