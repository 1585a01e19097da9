//! Prints what the committed robust gain's SDP returns on this machine (crate feature
//! `sdp`): the optimal `s`, `e_0`, `K`, the vertex radii, and how `s` and `K` move with
//! `e_0` across the search's final bracket and as the solver's tolerances are tightened.
//! Run under different `OPENBLAS_CORETYPE` / `OPENBLAS_NUM_THREADS` to measure the spread
//! that `tests/robust_gain_sdp.rs`'s tolerances must cover:
//!
//! ```sh
//! cargo run --release -p rig-tools --features sdp --example robust_gain_spread
//! ```

use rig_tools::design::robust_gain::{self, FORCE_SCALE_BRACKET};
use rig_tools::design::robust_gain_file::RobustGainFile;
use rig_tools::design::sdp::Tolerances;
use std::path::PathBuf;

fn line(tag: &str, d: &robust_gain::RobustDesign) {
    let k = &d.gain;
    let r = d.design.check_gain(&d.gain, 2);
    println!(
        "{tag}: e0 {:.6e} s {:.6e} dual {:.6e} feasible {:.6e} {} cond {:.4e} lmin(Q) {:.4e} margins.min {:.3e} \
         K [{:.9e} {:.3e} {:.3e}; {:.3e} {:.9e} {:.9e}] rho [{:.9} {:.9} {:.9} {:.9}]",
        d.force_scale,
        d.margin(),
        d.dual_margin,
        d.feasible_margin().unwrap_or(f64::NAN),
        d.solver,
        d.condition(),
        d.certificate.q.symmetric_eigenvalues().min(),
        d.margins().min(),
        k[(0, 0)],
        k[(0, 1)],
        k[(0, 2)],
        k[(1, 0)],
        k[(1, 1)],
        k[(1, 2)],
        r.vertices[0].radius,
        r.vertices[1].radius,
        r.vertices[2].radius,
        r.vertices[3].radius,
    );
}

fn main() {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/arm/robust-gain.toml");
    let f = RobustGainFile::load(&path).unwrap();
    let best = robust_gain::best_force_scale(&f.design).unwrap();
    line("best", &best);
    let l0 = best.force_scale.log10();
    for dl in [
        -0.2,
        -0.05,
        -FORCE_SCALE_BRACKET,
        0.0,
        FORCE_SCALE_BRACKET,
        0.05,
        0.2,
    ] {
        let d = robust_gain::solve(&f.design, 10f64.powf(l0 + dl)).unwrap();
        line(&format!("dlog {dl:+.3}"), &d);
    }
    for tol in [1e-9, 1e-10, 1e-11] {
        match robust_gain::solve_with(&f.design, best.force_scale, &Tolerances::uniform(tol)) {
            Ok(d) => line(&format!("tol {tol:.0e}"), &d),
            Err(e) => println!("tol {tol:.0e}: {e}"),
        }
    }
    let mut perturbed = vec![
        ("committed".to_string(), f.gain),
        ("fresh".to_string(), best.gain),
    ];
    for (r, c) in [(0, 0), (1, 1), (1, 2)] {
        for factor in [0.95, 1.05] {
            let mut k = f.gain;
            k[(r, c)] *= factor;
            perturbed.push((format!("K[{r}][{c}] x {factor}"), k));
        }
    }
    for (name, k) in perturbed {
        let d = robust_gain::certify_gain(&f.design, &k, best.force_scale).unwrap();
        line(&format!("certify {name}"), &d);
    }
    if std::env::args().any(|a| a == "--tight-search") {
        let d = robust_gain::best_force_scale_with(&f.design, &Tolerances::uniform(1e-10)).unwrap();
        line("best tol 1e-10", &d);
    }
}
