//! `ipc-types/include/adaptive_rig.h` against the library: the functions it declares are
//! the functions the library exports, its constants are the Rust ones, and the sizes and
//! offsets of its structs are the Rust layout, as the machine's C and C++ compilers see
//! them.

use adaptive_rig::C_HEADER;
use adaptive_rig::plant::*;
use adaptive_rig::plant_config::*;
use adaptive_rig::report::ArPlantReport;
use adaptive_rig::status;
use std::collections::BTreeSet;
use std::mem::{offset_of, size_of};
use std::path::{Path, PathBuf};
use std::process::Command;

fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn include_dir() -> PathBuf {
    crate_dir().join("../include")
}

/// The `ar_` names followed by `(` in `text`, from the position of `from` on each line.
fn ar_names_before_paren(text: &str, marker: impl Fn(&str) -> Option<usize>) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    for line in text.lines() {
        let Some(start) = marker(line) else { continue };
        let rest = &line[start..];
        if let Some(open) = rest.find('(') {
            let name = rest[..open].trim();
            let name = name.rsplit([' ', '*']).next().unwrap_or(name);
            if name.starts_with("ar_") {
                names.insert(name.to_string());
            }
        }
    }
    names
}

/// The functions the crate exports: every `extern "C" fn ar_…` of its sources.
fn exported() -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    for entry in std::fs::read_dir(crate_dir().join("src")).unwrap() {
        let text = std::fs::read_to_string(entry.unwrap().path()).unwrap();
        names.extend(ar_names_before_paren(&text, |l| {
            l.find("extern \"C\" fn ")
                .map(|i| i + "extern \"C\" fn ".len())
        }));
    }
    names
}

/// The functions the header declares: every line at the top level that has a return type
/// and `ar_…(`.
fn declared() -> BTreeSet<String> {
    ar_names_before_paren(C_HEADER, |l| {
        let t = l.trim_start();
        let top_level = l.len() == t.len();
        let is_decl = top_level
            && !t.starts_with('#')
            && !t.starts_with("/*")
            && !t.starts_with('*')
            && !t.starts_with("typedef")
            && t.contains("ar_")
            && t.contains('(');
        is_decl.then_some(0)
    })
}

#[test]
fn the_header_declares_exactly_the_exported_functions() {
    let exported = exported();
    let declared = declared();
    assert!(exported.len() >= 20, "found only {exported:?}");
    assert_eq!(
        exported, declared,
        "exported (left) and declared (right) differ"
    );
    for required in [
        "ar_plant_open",
        "ar_plant_publish",
        "ar_plant_take",
        "ar_plant_report",
        "ar_plant_report_json",
        "ar_plant_close",
        "ar_monotonic_ns",
        "ar_sleep_until_ns",
        "ar_controller_open",
        "ar_controller_receive",
        "ar_controller_send",
        "ar_controller_close",
        "ar_last_error",
    ] {
        assert!(exported.contains(required), "{required}");
    }
}

/// `#define NAME value` of the header, as a number (`(-3)` and `0x1u` accepted).
fn header_define(name: &str) -> i64 {
    let text = C_HEADER
        .lines()
        .find_map(|l| l.strip_prefix(&format!("#define {name} ")))
        .unwrap_or_else(|| panic!("the header does not define {name}"));
    let v = text.trim().trim_start_matches('(').trim_end_matches(')');
    v.parse()
        .unwrap_or_else(|_| panic!("{name} = {text} is not a number"))
}

#[test]
fn the_header_constants_are_the_rust_constants() {
    for (code, name) in status::ALL {
        assert_eq!(
            header_define(name.to_str().unwrap()),
            i64::from(code),
            "{name:?}"
        );
    }
    let pairs = [
        ("AR_MODE_REAL_TIME", AR_MODE_REAL_TIME),
        ("AR_MODE_LOCKSTEP", AR_MODE_LOCKSTEP),
        ("AR_LATE_HOLD", AR_LATE_HOLD),
        ("AR_LATE_SAFE", AR_LATE_SAFE),
        ("AR_LATE_PLAN", AR_LATE_PLAN),
        ("AR_WAIT_NOW", AR_WAIT_NOW),
        ("AR_WAIT_AT", AR_WAIT_AT),
        ("AR_WAIT_UNTIL", AR_WAIT_UNTIL),
        ("AR_WAIT_LOCKSTEP", AR_WAIT_LOCKSTEP),
        ("AR_INPUT_ANSWERED", AR_INPUT_ANSWERED),
        ("AR_INPUT_PLAN", AR_INPUT_PLAN),
        ("AR_INPUT_HELD", AR_INPUT_HELD),
        ("AR_INPUT_SAFE", AR_INPUT_SAFE),
        ("AR_INPUT_WATCHDOG_SAFE", AR_INPUT_WATCHDOG_SAFE),
        ("AR_PLANT_CONFIG_SIZE", size_of::<ArPlantConfig>() as i32),
        ("AR_PLANT_REPORT_SIZE", size_of::<ArPlantReport>() as i32),
    ];
    for (name, value) in pairs {
        assert_eq!(header_define(name), i64::from(value), "{name}");
    }
}

/// The field names of `typedef struct <tag> { … }` in the header, in order.
fn header_fields(tag: &str) -> Vec<String> {
    let start = C_HEADER
        .find(&format!("typedef struct {tag} {{"))
        .unwrap_or_else(|| panic!("no struct {tag}"));
    let body = &C_HEADER[start..];
    let body = &body[body.find('{').unwrap() + 1..body.find('}').unwrap()];
    body.lines()
        .filter_map(|l| {
            let decl = l.split("/*").next().unwrap().trim();
            let decl = decl.strip_suffix(';')?;
            Some(decl.rsplit([' ', '*']).next().unwrap().to_string())
        })
        .collect()
}

/// `(field, offset)` of every field named, from the Rust type.
macro_rules! offsets {
    ($t:ty, [$($f:ident),* $(,)?]) => {
        vec![$((stringify!($f), offset_of!($t, $f))),*]
    };
}

/// A struct of the header: its tag, its typedef name, the Rust size and field offsets.
type Layout = (
    &'static str,
    &'static str,
    usize,
    Vec<(&'static str, usize)>,
);

fn layouts() -> Vec<Layout> {
    vec![
        (
            "ar_plant_config",
            "ar_plant_config_t",
            size_of::<ArPlantConfig>(),
            offsets!(
                ArPlantConfig,
                [
                    rig,
                    counts,
                    period_ns,
                    mode,
                    late_policy,
                    plan_fallback,
                    verbose,
                    deadline,
                    safe_input,
                    watchdog_periods,
                    lockstep_timeout_s,
                    peer_timeout_s,
                    label,
                ]
            ),
        ),
        (
            "ar_plant_report",
            "ar_plant_report_t",
            size_of::<ArPlantReport>(),
            offsets!(
                ArPlantReport,
                [
                    samples,
                    actuations_applied,
                    misses,
                    plan_entries_applied,
                    misses_held_or_safe,
                    misses_before_first_answer,
                    late_discarded,
                    invalid_discarded,
                    ahead_dropped,
                    foreign_discarded,
                    new_services,
                    watchdog_trips,
                    watchdog_recoveries,
                    safe_output_samples,
                    stalls_injected,
                    stall_acks,
                    wall_time_s,
                    service_pid,
                    gave_up,
                ]
            ),
        ),
    ]
}

#[test]
fn the_header_structs_have_the_rust_fields_in_order() {
    for (tag, _, _, fields) in layouts() {
        let rust: Vec<&str> = fields.iter().map(|(f, _)| *f).collect();
        assert_eq!(header_fields(tag), rust, "{tag}");
    }
}

/// A C (or C++) file asserting at compile time the Rust sizes and offsets of the header's
/// structs, and calling nothing (it only has to compile).
fn layout_check_source(cxx: bool) -> String {
    let assert = if cxx {
        "static_assert"
    } else {
        "_Static_assert"
    };
    let mut s = String::from("#include \"adaptive_rig.h\"\n");
    for (_, ty, size, fields) in layouts() {
        s += &format!("{assert}(sizeof({ty}) == {size}, \"sizeof {ty}\");\n");
        for (f, off) in fields {
            s += &format!("{assert}(offsetof({ty}, {f}) == {off}, \"offset of {ty}.{f}\");\n");
        }
    }
    s += "int main(void) { return 0; }\n";
    s
}

/// Compiles `source` with `compiler` and `flags` (syntax only); `false` when the compiler
/// is missing (said on stderr), panics with its output when it refuses the file.
fn compiles(compiler: &str, flags: &[&str], file: &str, source: &str) -> bool {
    let dir = std::env::temp_dir().join(format!("ar-c-header-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(file);
    std::fs::write(&path, source).unwrap();
    let out = Command::new(compiler)
        .args(flags)
        .arg("-fsyntax-only")
        .arg("-I")
        .arg(include_dir())
        .arg(&path)
        .output();
    let out = match out {
        Ok(o) => o,
        Err(e) => {
            eprintln!("no {compiler} ({e}): the header was not compiled");
            return false;
        }
    };
    assert!(
        out.status.success(),
        "{compiler} refused {}:\n{}\n{source}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    true
}

#[test]
fn the_header_compiles_as_c_with_the_rust_layout() {
    compiles(
        "cc",
        &["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic"],
        "layout.c",
        &layout_check_source(false),
    );
}

#[test]
fn the_header_compiles_as_cxx_with_the_rust_layout() {
    compiles(
        "c++",
        &["-x", "c++", "-std=c++11", "-Wall", "-Wextra", "-Werror"],
        "layout.cpp",
        &layout_check_source(true),
    );
    // A C++ caller compiles (tests/tests/c_peers.rs links one).
    compiles(
        "c++",
        &["-x", "c++", "-Wall", "-Werror"],
        "use.cpp",
        "#include \"adaptive_rig.h\"\nint main() { ar_plant_t* p = nullptr; return ar_plant_close(p) == AR_OK ? 0 : 1; }\n",
    );
}
