//! The scenario schema's outline of `[plant]` (what the service reads of it without the
//! simulator: channel counts, noise, tones) agrees with the plant plant-proxy builds from
//! the same table, for every scenario of `scenarios/` that has one.

use rig_scenario::plant_outline::PlantOutline;
use std::f64::consts::PI;
use std::path::Path;

fn scenario_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            scenario_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "toml") {
            out.push(p);
        }
    }
}

#[test]
fn the_outline_of_every_scenario_plant_agrees_with_the_plant_built_from_it() {
    let mut files = Vec::new();
    scenario_files(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios"),
        &mut files,
    );
    let mut checked = 0;
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let table: toml::Table = toml::from_str(&text).unwrap();
        let Some(plant_table) = table.get("plant") else {
            continue;
        };
        let origin = f.display().to_string();
        let s = plant_proxy::scenario::parse(&text, &origin).unwrap();
        let (p, o) = (&s.plant, PlantOutline::new(plant_table));
        if let Ok(c) = o.channel_counts() {
            let counts = [c.n_y, c.n_z, c.n_r, c.n_u].map(|n| n as usize);
            assert_eq!(counts, [p.n_y(), p.n_z(), p.n_r(), p.n_u()], "{origin}");
        }
        for (signal, std) in [("y", &p.noise.y_std), ("z", &p.noise.z_std)] {
            for (i, s) in std.iter().enumerate() {
                if let Some(o) = o.noise_std(signal, i) {
                    assert_eq!(o, *s, "{origin}: {signal}[{i}]");
                }
            }
        }
        let mut omegas: Vec<f64> = Vec::new();
        for t in &p.disturbance.tones {
            if !omegas.contains(&t.omega) {
                omegas.push(t.omega);
            }
        }
        let hz = o.tone_frequencies_hz();
        assert_eq!(hz.len(), omegas.len(), "{origin}: tones");
        for (f, w) in hz.iter().zip(&omegas) {
            assert!(
                (2.0 * PI * f - w).abs() <= 1e-12 * w,
                "{origin}: tone {f} Hz, {w} rad/s"
            );
        }
        checked += 1;
    }
    assert!(
        checked >= 15,
        "only {checked} scenarios with a [plant] table"
    );
}
