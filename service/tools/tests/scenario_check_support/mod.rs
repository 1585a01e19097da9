//! Shared by the configuration tests: the scenario files of `scenarios/`, edited as TOML
//! tables, and the loading of both halves of a scenario.

#![allow(dead_code)]

use rig_tools::scenario_check::ScenarioCheck;
use service::config::ConfigError;
use std::path::{Path, PathBuf};

/// The folder of the scenario files.
pub fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios")
}

/// Every complete scenario of `scenarios/` (a `[rig]` table; not a controller or
/// target-model file), as `(origin, table)`.
pub fn corpus() -> Vec<(String, toml::Table)> {
    let mut files = Vec::new();
    let mut dirs = vec![scenarios_dir()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "toml") {
                files.push(p);
            }
        }
    }
    files.sort();
    files
        .into_iter()
        .filter_map(|p| {
            let table: toml::Table = toml::from_str(&std::fs::read_to_string(&p).unwrap()).ok()?;
            table
                .contains_key("rig")
                .then(|| (p.display().to_string(), table))
        })
        .collect()
}

/// The corpus and, for each controller file of `scenarios/` (a `[controller]` table and no
/// `[rig]`), the main job's scenario with that controller, named by the controller file
/// (relative file names in it resolve from its folder).
pub fn corpus_with_controllers() -> Vec<(String, toml::Table)> {
    let mut all = corpus();
    let base = scenario("acoustic-rig.toml");
    for name in [
        "rcac/acoustic-rls.toml",
        "rcac/acoustic-gradient.toml",
        "lti/acoustic-resonant.toml",
        "identify/excitation.toml",
    ] {
        let c = scenario(name);
        let mut t = base.clone();
        for (k, v) in c {
            t.insert(k, v);
        }
        all.push((scenarios_dir().join(name).display().to_string(), t));
    }
    all
}

/// The plant half of `t` alone, as plant-proxy loads it (scenario and discretization):
/// the refusal as `(field, message)`.
pub fn check_plant_half(t: &toml::Table, origin: &str) -> Result<(), (String, String)> {
    let text = toml::to_string(t).unwrap();
    let s = plant_proxy::scenario::parse(&text, origin)
        .map_err(|e| (e.field().unwrap_or("").to_string(), e.to_string()))?;
    plant_proxy::sim::PlantSim::new(&s.plant, s.rig.sample_period)
        .map(|_| ())
        .map_err(|e| ("plant".to_string(), e.to_string()))
}

/// The scenario `name` of `scenarios/` as a table.
pub fn scenario(name: &str) -> toml::Table {
    let text = std::fs::read_to_string(scenarios_dir().join(name)).unwrap();
    toml::from_str(&text).unwrap()
}

/// The value at the dotted `path` of `t` (`"service.report.window"`, `"plant.modal.modes"`,
/// with `[i]` for an array entry: `"plant.truss.nodes[2].mass"`), created when a table
/// on the way has no such key.
pub fn set(t: &mut toml::Table, path: &str, v: toml::Value) {
    let mut keys: Vec<(String, Option<usize>)> = path
        .split('.')
        .map(|k| match k.split_once('[') {
            Some((k, i)) => (
                k.to_string(),
                Some(i.trim_end_matches(']').parse().unwrap()),
            ),
            None => (k.to_string(), None),
        })
        .collect();
    let (last, last_index) = keys.pop().unwrap();
    let mut cur = t;
    for (k, i) in keys {
        let mut v = cur
            .entry(k)
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let Some(i) = i {
            v = &mut v.as_array_mut().unwrap()[i];
        }
        cur = v.as_table_mut().unwrap();
    }
    match last_index {
        Some(i) => cur.get_mut(&last).unwrap().as_array_mut().unwrap()[i] = v,
        None => {
            cur.insert(last, v);
        }
    }
}

/// Removes the key at the dotted `path` (no array indices).
pub fn remove(t: &mut toml::Table, path: &str) {
    let (head, last) = path.rsplit_once('.').unwrap_or(("", path));
    let mut cur = t;
    for k in head.split('.').filter(|k| !k.is_empty()) {
        cur = cur.get_mut(k).unwrap().as_table_mut().unwrap();
    }
    cur.remove(last);
}

/// Both halves of the scenario `t` loaded, as `rig check` loads them.
pub fn check(t: &toml::Table, origin: &str) -> Result<ScenarioCheck, ConfigError> {
    ScenarioCheck::parse(&toml::to_string(t).unwrap(), origin)
}

/// The refusal of `t`, which must be refused naming `field`: the error's field, and the
/// message `<origin>: field '<field>': …`.
pub fn assert_refused(t: &toml::Table, field: &str) -> ConfigError {
    let origin = format!("{}/case.toml", scenarios_dir().display());
    let e = match check(t, &origin) {
        Ok(_) => panic!("accepted, expected a refusal naming {field}"),
        Err(e) => e,
    };
    assert_eq!(e.field, field, "{e}");
    assert!(
        e.to_string()
            .starts_with(&format!("{origin}: field '{field}': ")),
        "{e}"
    );
    e
}
