//! `plant-jack check`: the repository's JACK scenario is accepted, and a bad `[jack]` table
//! is refused with exit code 2, naming the file and the field (no JACK server is needed).

use std::path::{Path, PathBuf};
use std::process::Command;

fn scenario(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenarios")
        .join(name)
}

fn check(path: &Path) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_plant-jack"))
        .arg("check")
        .arg(path)
        .output()
        .expect("plant-jack runs");
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code(), text)
}

#[test]
fn the_jack_scenario_is_accepted() {
    let (code, text) = check(&scenario("jack/acoustic-rig.toml"));
    assert_eq!(code, Some(0), "{text}");
    for part in [
        ": ok (rig 'acoustic-rig-jack', 8000 Hz, channels y=1 z=1 u=2",
        "JACK server 'adaptive-rig', client 'adaptive-rig-daq', budget 0.5",
        "u [\"room:speaker-u0\", \"room:speaker-u1\"]",
    ] {
        assert!(text.contains(part), "{part}: {text}");
    }
}

#[test]
fn a_bad_jack_table_is_refused_naming_the_file_and_the_field() {
    let dir = std::env::temp_dir().join(format!("plant-jack-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(scenario("jack/acoustic-rig.toml")).unwrap();
    for (old, new, field) in [
        ("budget = 0.5", "budget = 2.0", "field 'jack.budget'"),
        (
            "y = [\"room:mic-y0\"]",
            "y = [\"room:mic-y0\", \"room:mic-z0\"]",
            "field 'jack.y': 2 port(s)",
        ),
        (
            "u-full-scale = [40.0, 40.0]",
            "u-full-scale = [0.0, 40.0]",
            "field 'jack.u-full-scale'",
        ),
        (
            "period-frames = 64",
            "period = 64",
            "unknown field `period`",
        ),
    ] {
        assert!(text.contains(old), "{old}");
        let path = dir.join("bad.toml");
        std::fs::write(&path, text.replace(old, new)).unwrap();
        let (code, out) = check(&path);
        assert_eq!(code, Some(2), "{out}");
        assert!(
            out.contains(&path.display().to_string()) && out.contains(field),
            "{field}: {out}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
