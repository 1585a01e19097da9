use super::*;

/// An independent recursion: the difference equation written out with plain histories
/// (`u[k]`, `y[k]` for `k ≥ 0`, zero before), same order of summation.
fn reference(num: &[f64], den: &[f64], u: &[f64]) -> Vec<f64> {
    let mut y: Vec<f64> = Vec::with_capacity(u.len());
    for k in 0..u.len() {
        let mut acc = 0.0;
        for j in 1..num.len() {
            if k >= j {
                acc += num[j] * u[k - j];
            }
        }
        for i in 1..den.len() {
            if k >= i {
                acc -= den[i] * y[k - i];
            }
        }
        y.push(acc);
    }
    y
}

fn run(tf: &DiscreteTf, u: &[f64]) -> Vec<f64> {
    let mut p = DifferenceEquation::new(tf.clone());
    u.iter()
        .map(|&uk| {
            let y = p.output();
            p.step(uk);
            y
        })
        .collect()
}

/// A deterministic, irregular input sequence.
fn input(len: usize) -> Vec<f64> {
    (0..len)
        .map(|k| {
            let k = k as f64;
            (0.37 * k).sin() + 0.5 * (1.91 * k + 0.2).cos() + if k > 50.0 { 1.0 } else { 0.0 }
        })
        .collect()
}

#[test]
fn the_output_is_the_difference_equation_bit_for_bit() {
    let u = input(2000);
    let cases: [(&[f64], &[f64]); 4] = [
        (
            &[0.0, 1.0, -0.5],
            &[1.0, -std::f64::consts::FRAC_1_SQRT_2, 0.25],
        ),
        (&[0.0, 1.0, -1.5], &[1.0, 0.3, 0.81]),
        (&[0.0, 0.0, 0.0, 0.2, 0.1], &[1.0, -0.9]),
        (&[0.0, 0.5], &[1.0, -1.2, 0.6, -0.1]),
    ];
    for (num, den) in cases {
        let tf = DiscreteTf::new(num.to_vec(), den.to_vec()).unwrap();
        let got = run(&tf, &u);
        let want = reference(num, den, &u);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(&want), "{num:?} / {den:?}");
        assert!(got.iter().any(|&y| y != 0.0));
    }
}

#[test]
fn the_first_samples_follow_by_hand() {
    // y_k = u_{k−1} − 0.5 u_{k−2} + 0.5 y_{k−1} with a unit step: 0, 1, 1, 1, 1, …
    let tf = DiscreteTf::new(vec![0.0, 1.0, -0.5], vec![1.0, -0.5]).unwrap();
    let y = run(&tf, &[1.0; 6]);
    assert_eq!(y, [0.0, 1.0, 1.0, 1.0, 1.0, 1.0]);
    // An impulse through y_k = y_{k−1}·0.5 + u_{k−1}: 0, 1, 0.5, 0.25.
    let tf = DiscreteTf::new(vec![0.0, 1.0], vec![1.0, -0.5]).unwrap();
    assert_eq!(run(&tf, &[1.0, 0.0, 0.0, 0.0]), [0.0, 1.0, 0.5, 0.25]);
}

#[test]
fn the_state_holds_past_outputs_then_past_inputs_and_reset_returns_to_rest() {
    let tf = DiscreteTf::new(vec![0.0, 1.0, 2.0], vec![1.0, -0.5, 0.1]).unwrap();
    let mut p = DifferenceEquation::new(tf);
    assert_eq!(p.state(), &[0.0; 4]);
    p.step(3.0); // y_1 = 3
    p.step(-1.0); // y_2 = −1 + 6 + 0.5·3 = 6.5
    assert_eq!(p.output(), 6.5);
    assert_eq!(p.state(), &[3.0, 0.0, -1.0, 3.0]);
    p.reset();
    assert_eq!(p.state(), &[0.0; 4]);
    assert_eq!(p.output(), 0.0);
}

#[test]
fn a_leading_denominator_coefficient_is_divided_out() {
    let g = DiscreteTf::new(vec![0.0, 2.0, -1.0], vec![2.0, -1.0, 0.5]).unwrap();
    assert_eq!(g.num(), &[0.0, 1.0, -0.5]);
    assert_eq!(g.den(), &[1.0, -0.5, 0.25]);
    assert_eq!((g.n(), g.m(), g.n_states()), (2, 2, 4));
}

#[test]
fn bad_coefficients_are_refused_naming_the_key() {
    let e = |num: Vec<f64>, den: Vec<f64>| DiscreteTf::new(num, den).unwrap_err();
    let cases = [
        (
            e(vec![0.0, 1.0], vec![]),
            "den",
            DiscreteTfError::EmptyDenominator,
        ),
        (
            e(vec![0.0, 1.0], vec![0.0, 1.0]),
            "den",
            DiscreteTfError::ZeroLeadingDenominator,
        ),
        (e(vec![], vec![1.0]), "num", DiscreteTfError::EmptyNumerator),
        (
            e(vec![0.3, 1.0], vec![1.0]),
            "num",
            DiscreteTfError::DirectFeedthrough(0.3),
        ),
        (
            e(vec![0.0, f64::NAN], vec![1.0]),
            "num[1]",
            DiscreteTfError::NonFinite {
                which: "num",
                index: 1,
            },
        ),
        (
            e(vec![0.0, 1.0], vec![1.0, 0.5, f64::INFINITY]),
            "den[2]",
            DiscreteTfError::NonFinite {
                which: "den",
                index: 2,
            },
        ),
        (
            e(vec![0.0, 1e300], vec![1e-300, 1.0]),
            "den",
            DiscreteTfError::Overflow,
        ),
        (
            e(vec![0.0; MAX_COEFFICIENTS + 1], vec![1.0]),
            "num",
            DiscreteTfError::TooLong {
                which: "num",
                len: MAX_COEFFICIENTS + 1,
            },
        ),
    ];
    for (got, key, want) in cases {
        assert_eq!(got, want);
        assert_eq!(got.key(), key);
        assert!(!got.to_string().is_empty());
    }
}

#[test]
fn descending_powers_of_z_pad_to_the_larger_degree() {
    // (q⁻¹ − 0.5 q⁻²)/(1 − 0.5 q⁻¹) = (z − 0.5)/(z² − 0.5 z): a pole at 0 from the delay.
    let g = DiscreteTf::new(vec![0.0, 1.0, -0.5], vec![1.0, -0.5]).unwrap();
    assert_eq!(g.descending(), (vec![1.0, -0.5], vec![1.0, -0.5, 0.0]));
    let mut p: Vec<f64> = g.poles().unwrap().iter().map(|c| c.re).collect();
    p.sort_by(f64::total_cmp);
    assert!((p[0]).abs() < 1e-15 && (p[1] - 0.5).abs() < 1e-15, "{p:?}");
    let z = g.zeros().unwrap();
    assert_eq!(z.len(), 1);
    assert!((z[0].re - 0.5).abs() < 1e-15 && z[0].im == 0.0);
    let zero = DiscreteTf::new(vec![0.0], vec![1.0, 0.3]).unwrap();
    assert_eq!(zero.descending().0, vec![0.0]);
    assert!(zero.zeros().unwrap().is_empty());
}
