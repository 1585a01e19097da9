//! `kind = "sampling-arm"`: the adaptive force controller of chapter 7
//! ([`ArmController`](control::arm::controller::ArmController), Algorithm 3: feedback
//! linearization (7.31), robust gain (7.39)–(7.41), PCAC augmentation (7.42)–(7.61)) with
//! the joint hold out of contact. The rig must have `y = 7`
//! (`[θ_1, θ_2, θ̇_1, θ̇_2, ẋ, ẏ, F_c]`), `r = 1` (`F_d`) and `u = 2` (the joint torques).
//!
//! ```toml
//! [controller]
//! kind = "sampling-arm"
//! robust-gain = "robust-gain.toml"  # the robust-gain file, relative to this file's folder,
//!                                   # or inline: [[k11, k12, k13], [k21, k22, k23]]
//! u-min = -500.0                    # optional torque limits (N m): scalar or per joint
//! u-max = 500.0
//!
//! [controller.arm]                  # the nominal spacecraft of (7.31); each optional,
//! m-sc = 420.0                      # defaults §7.3's: m-sc, m1, m2, m-s (kg), l1, l2,
//!                                   # r1, r2 (m), i1, i2 (kg m²)
//!
//! [controller.hold]                 # the joint hold while r = 0
//! kp = 1000.0                       # K_p (N m/rad): scalar or per joint (default 1000)
//! kd = 200.0                        # K_d (N m s/rad): scalar or per joint (default 200)
//!
//! [controller.pcac]                 # optional: the PCAC augmentation (without: robust only)
//! n-hat = 1                         # the fields of kind = "pcac" (see the pcac module),
//! p0 = 10.0                         # for p = 5 outputs ζ and m = 2 inputs u_aug, no commands
//! horizon = 50
//! tracking = [[0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]]
//! q = [1000.0, 100.0, 1.0]
//! u-min = -100.0                    # … r, u-max, du-min, du-max, timing, warm-start,
//!                                   # qp-max-iterations, fast-path, trace-limit, lambda
//! theta0 = "contact-model"          # w_0 from the zero-order-hold model of (7.35)–(7.36),
//!                                   # or a scalar, or 35 values (n̂ = 1)
//! [controller.pcac.forgetting]      # as [controller.forgetting]
//! [controller.pcac.prior]           # the contact model of theta0 = "contact-model"
//! k-s = 100.0                       # N/m (default 100)
//! c-s = 1000.0                      # N s/m (default 1000)
//! theta = [0.7853981633974483, 1.5707963267948966]   # θ̄ at contact (default (π/4, π/2))
//! qd = [0.0, 0.0, 0.0, -0.1]        # q̇ at contact (default (0, 0, 0, −0.1))
//! ```
//!
//! The robust-gain file ([`RobustGainFile`]) must have the rig's sample period.

use super::bounds::MAX_THETA0;
use super::controller::{ControllerConfig, Rig, output_limits, param_error};
use super::pcac::{RawPcac, read as read_pcac};
use super::robust_gain_file::RobustGainFile;
use super::values::{ScalarOrVec, magnitudes, per_channel};
use super::{ConfigError, ErrFn};
use control::arm::controller::{ArmControllerParams, JointHold};
use control::arm::feedback_linearization::{ContactPrior, FeedbackLinearization};
use control::{Dimensions, ParamError};
use rig_scenario::spacecraft::SpacecraftTable;
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawArm {
    #[allow(dead_code)]
    kind: String,
    robust_gain: Option<RawGain>,
    arm: Option<SpacecraftTable>,
    hold: Option<RawHold>,
    pcac: Option<toml::Value>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
}

/// `robust-gain`: a file name or the matrix.
#[derive(Deserialize)]
#[serde(untagged)]
enum RawGain {
    File(String),
    Inline(Vec<Vec<f64>>),
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawHold {
    kp: Option<ScalarOrVec>,
    kd: Option<ScalarOrVec>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawPrior {
    k_s: Option<f64>,
    c_s: Option<f64>,
    theta: Option<Vec<f64>>,
    qd: Option<Vec<f64>>,
}

/// The table of the PCAC augmentation.
const PCAC: &str = "controller.pcac";

/// Reads `kind = "sampling-arm"` into [`ArmControllerParams`] and validates them for the
/// rig's channels.
pub(super) fn parse(
    raw: RawArm,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    let robust_gain = robust_gain(raw.robust_gain, rig, err)?;
    let arm = raw.arm.unwrap_or_default().params();
    let hold = raw.hold.unwrap_or_default();
    let d = JointHold::DEFAULT;
    let hold = JointHold {
        kp: two(&hold.kp, d.kp, "controller.hold.kp", err)?,
        kd: two(&hold.kd, d.kd, "controller.hold.kd", err)?,
    };
    let limits = output_limits(&raw.u_min, &raw.u_max, 2, err)?;
    let mut params = ArmControllerParams {
        arm,
        robust_gain,
        hold,
        pcac: None,
        limits,
    };
    // The arm's own fields first (the prior needs a valid spacecraft), then PCAC's.
    let dims = crate::wire::dimensions(rig.counts);
    params.validate(dims).map_err(|e| param_error(e, err))?;
    if let Some(table) = raw.pcac {
        let pcac = pcac(table, &params, rig.period, err)?;
        params.pcac = Some(pcac);
        params.validate(dims).map_err(|e| param_error(e, err))?;
    }
    Ok(ControllerConfig::SamplingArm {
        params: Box::new(params),
    })
}

/// `K` from the robust-gain file (relative to the controller file's folder) or inline.
fn robust_gain(
    raw: Option<RawGain>,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<[f64; 6], ConfigError> {
    const FIELD: &str = "controller.robust-gain";
    let raw = raw.ok_or_else(|| {
        err(
            FIELD,
            "missing: the robust-gain file (e.g. \"robust-gain.toml\") or K inline, \
             [[k11, k12, k13], [k21, k22, k23]]"
                .into(),
        )
    })?;
    match raw {
        RawGain::Inline(rows) => {
            if rows.len() != 2 || rows.iter().any(|r| r.len() != 3) {
                return Err(err(
                    FIELD,
                    "K must be 2 × 3 (τ_f = K [ẋ, ẏ, e]), two rows of three".into(),
                ));
            }
            let mut k = [0.0; 6];
            for (d, s) in k.iter_mut().zip(rows.iter().flatten()) {
                *d = *s;
            }
            Ok(k)
        }
        RawGain::File(name) => {
            let path = Path::new(&name);
            let path = if path.is_absolute() {
                path.to_path_buf()
            } else {
                rig.base_dir.join(path)
            };
            let file = RobustGainFile::load(&path).map_err(|m| err(FIELD, m))?;
            let (ts, rig_ts) = (file.sample_period, rig.period);
            if (ts - rig_ts).abs() > 1e-9 * rig_ts {
                return Err(err(
                    FIELD,
                    format!(
                        "{}: field 'robust-gain.sample-period': the gain was designed for \
                         {ts} s, the rig samples every {rig_ts} s",
                        path.display()
                    ),
                ));
            }
            Ok(file.gain())
        }
    }
}

/// A scalar for both joints or one value each, `default` when absent.
fn two(
    v: &Option<ScalarOrVec>,
    default: [f64; 2],
    field: &str,
    err: &ErrFn<'_>,
) -> Result<[f64; 2], ConfigError> {
    if v.is_none() {
        return Ok(default);
    }
    let g = per_channel(v, 2, 0.0, field, err)?;
    Ok([g[0], g[1]])
}

/// The `[controller.pcac]` table: the PCAC fields of `kind = "pcac"` for `ζ` (5 outputs)
/// and `u_aug` (2 inputs), with `theta0 = "contact-model"` and `[controller.pcac.prior]`.
fn pcac(
    table: toml::Value,
    arm: &ArmControllerParams,
    period: f64,
    err: &ErrFn<'_>,
) -> Result<control::pcac::PcacParams, ConfigError> {
    let toml::Value::Table(mut table) = table else {
        return Err(err(PCAC, "must be a table".into()));
    };
    if table.contains_key("kind") {
        return Err(err(
            &format!("{PCAC}.kind"),
            "the augmentation is PCAC; the table takes no kind".into(),
        ));
    }
    let prior = table.remove("prior");
    let contact_model = match table.get("theta0") {
        Some(toml::Value::String(name)) if name == "contact-model" => {
            table.remove("theta0");
            true
        }
        Some(toml::Value::String(name)) => {
            return Err(err(
                &format!("{PCAC}.theta0"),
                format!("'{name}': give \"contact-model\", a number or 35 values"),
            ));
        }
        _ => false,
    };
    let raw: RawPcac = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| err(PCAC, e.to_string()))?;
    let pcac_dims = ArmControllerParams::pcac_dimensions();
    let (mut params, rule) = read_pcac(raw, PCAC, pcac_dims.n_y, pcac_dims.n_u, period, err)?;
    match (contact_model, prior) {
        (false, Some(_)) => {
            return Err(err(
                &format!("{PCAC}.prior"),
                "read only with theta0 = \"contact-model\"".into(),
            ));
        }
        (false, None) => {}
        (true, prior) => {
            let prior = contact_prior(prior, err)?;
            let theta0 = FeedbackLinearization::new(arm.arm)
                .pcac_prior(&prior, period)
                .map_err(|m| err(&format!("{PCAC}.prior"), m))?;
            if params.model.n_hat != 1 {
                return Err(err(
                    &format!("{PCAC}.theta0"),
                    format!(
                        "\"contact-model\" is the model of order n̂ = 1 (F̂_1 = −A_d, Ĝ_1 = B_d); \
                         n-hat is {}",
                        params.model.n_hat
                    ),
                ));
            }
            magnitudes(&theta0, MAX_THETA0, &format!("{PCAC}.prior"), err)?;
            params.model.theta0 = theta0;
        }
    }
    let mut with_feedback = arm.clone();
    with_feedback.pcac = Some(params.clone());
    let check = with_feedback
        .augmented_pcac()
        .and_then(|p| p.validate(pcac_dims));
    check.map_err(|e| {
        let e = rule.locate(e);
        let field = if e.field.is_empty() {
            PCAC.to_string()
        } else {
            format!("{PCAC}.{}", e.path())
        };
        err(&field, pcac_message(&e, pcac_dims))
    })?;
    Ok(params)
}

/// The kernel's message, with the channels PCAC sees named when they are at fault.
fn pcac_message(e: &ParamError, dims: Dimensions) -> String {
    if e.field.is_empty() {
        format!(
            "{} (the augmentation identifies ζ = [θ̇1, θ̇2, ẋ, ẏ, e]: p = {}, m = {}, no \
             commands)",
            e.message, dims.n_y, dims.n_u
        )
    } else {
        e.message.clone()
    }
}

/// `[controller.pcac.prior]`, §7.3's values where it gives none.
fn contact_prior(value: Option<toml::Value>, err: &ErrFn<'_>) -> Result<ContactPrior, ConfigError> {
    let field = format!("{PCAC}.prior");
    let raw: RawPrior = match value {
        None => RawPrior::default(),
        Some(v) => v
            .try_into()
            .map_err(|e: toml::de::Error| err(&field, e.to_string()))?,
    };
    let d = ContactPrior::CHAPTER_7;
    let fixed =
        |v: Option<Vec<f64>>, default: &[f64], name: &str| -> Result<Vec<f64>, ConfigError> {
            match v {
                None => Ok(default.to_vec()),
                Some(v) if v.len() == default.len() => Ok(v),
                Some(v) => Err(err(
                    &format!("{field}.{name}"),
                    format!("has {} values, expected {}", v.len(), default.len()),
                )),
            }
        };
    let theta = fixed(raw.theta, &d.theta, "theta")?;
    let qd = fixed(raw.qd, &d.qd, "qd")?;
    let prior = ContactPrior {
        k_s: raw.k_s.unwrap_or(d.k_s),
        c_s: raw.c_s.unwrap_or(d.c_s),
        theta: [theta[0], theta[1]],
        qd: [qd[0], qd[1], qd[2], qd[3]],
    };
    prior.validate().map_err(|e| param_error(e, err))?;
    Ok(prior)
}

#[cfg(test)]
mod tests {
    use super::super::refusal_cases::assert_refused_naming_fields;
    use super::super::{RobustGainFile, ServiceConfig};
    use super::*;
    use control::arm::dynamics::ArmParams;
    use control::mpc::condense::Weight;
    use control::pcac::PcacTiming;
    use std::path::PathBuf;

    const ROBUST: &str = include_str!("../../../scenarios/arm/robust.toml");
    const PCAC_FILE: &str = include_str!("../../../scenarios/arm/pcac.toml");
    /// The arm rig's channels at 2 kHz.
    const RIG: &str = "[rig]\nname = \"arm\"\nsample-period = 0.0005\n\
                       [service]\nchannels = { y = 7, z = 1, r = 1, u = 2 }\n";
    const K: [f64; 6] = [-3.0, 0.0, 0.0, 0.0, -190.0, 0.09];

    /// A folder with a robust-gain file of the sample period `ts` (and one of 1 ms as
    /// `other-gain.toml`); `name` keeps the tests' folders apart.
    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("arm-config-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (file, ts) in [("robust-gain.toml", 0.0005), ("other-gain.toml", 0.001)] {
            let gain = RobustGainFile {
                k: vec![K[..3].to_vec(), K[3..].to_vec()],
                sample_period: ts,
                decay_rate: Some(0.05),
                stiffness: Some([300.0, 2.7e5]),
                damping: Some([0.35, 1000.0]),
                margin: None,
                source: "the arm configuration's tests".into(),
            };
            std::fs::write(dir.join(file), gain.to_toml()).unwrap();
        }
        dir
    }

    fn origin(dir: &Path) -> String {
        dir.join("arm.toml").display().to_string()
    }

    fn params(text: &str, origin: &str) -> Result<Box<ArmControllerParams>, String> {
        let c = ServiceConfig::parse(text, origin).map_err(|e| e.to_string())?;
        match c.controller {
            ControllerConfig::SamplingArm { params } => Ok(params),
            other => panic!("not the arm: {other:?}"),
        }
    }

    #[test]
    fn the_chapter_7_controller_files_are_read_into_the_controller() {
        let dir = folder("read");
        let o = origin(&dir);
        let p = params(&format!("{RIG}{PCAC_FILE}"), &o).unwrap();
        assert_eq!(p.robust_gain, K);
        assert_eq!(p.arm, ArmParams::CHAPTER_7);
        assert_eq!(p.hold, JointHold::DEFAULT);
        assert!(p.limits.is_none());
        let pcac = p.pcac.as_ref().unwrap();
        assert_eq!((pcac.model.n_hat, pcac.model.p, pcac.model.m), (1, 5, 2));
        assert_eq!(pcac.model.p0, 10.0);
        let w0 = FeedbackLinearization::new(ArmParams::CHAPTER_7)
            .pcac_prior(&ContactPrior::CHAPTER_7, 0.0005)
            .unwrap();
        assert_eq!(pcac.model.theta0, w0);
        assert_eq!(
            pcac.model.rule,
            control::forgetting::ForgettingRule::FTest {
                tau_n: 40,
                tau_d: 200,
                eta: 0.1,
                alpha: 0.001
            }
        );
        assert_eq!(pcac.mpc.horizon, 50);
        assert_eq!(pcac.mpc.n_tracked, 3);
        assert_eq!(pcac.mpc.q, Weight::PerChannel(vec![1000.0, 100.0, 1.0]));
        assert_eq!(pcac.mpc.r, Weight::PerChannel(vec![1.0, 1.0]));
        assert_eq!(
            (pcac.mpc.u_min.clone(), pcac.mpc.u_max.clone()),
            (vec![-100.0; 2], vec![100.0; 2])
        );
        assert_eq!(pcac.mpc.move_bounds.as_ref().unwrap().max, vec![50.0; 2]);
        assert_eq!(pcac.timing, PcacTiming::SameStep);
        // The configuration validates, the controller builds, and answers compute-first.
        let c = ServiceConfig::parse(&format!("{RIG}{PCAC_FILE}"), &o).unwrap();
        assert!(!c.controller.answers_ahead());
        let built = c.controller.build(c.counts).unwrap();
        assert_eq!(built.kind(), "sampling-arm");
        assert_eq!(built.internal_names().len(), 16);
        // The robust controller alone.
        let p = params(&format!("{RIG}{ROBUST}"), &o).unwrap();
        assert!(p.pcac.is_none());
        assert_eq!(p.robust_gain, K);
        // K inline, torque limits, one gain per joint, another spacecraft.
        let text = format!("{RIG}{ROBUST}")
            .replace(
                "robust-gain = \"robust-gain.toml\"",
                "robust-gain = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]\nu-max = 50.0\nu-min = -50.0",
            )
            .replace("kd = 200.0", "kd = [150.0, 100.0]")
            .replace("m-sc = 420.0", "m-sc = 300.0");
        let p = params(&text, &o).unwrap();
        assert_eq!(p.robust_gain, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(p.hold.kd, [150.0, 100.0]);
        assert_eq!(p.arm.m_sc, 300.0);
        assert_eq!(p.limits.as_ref().unwrap().max, vec![50.0; 2]);
    }

    #[test]
    fn the_robust_gain_file_is_found_next_to_the_controller_file() {
        let dir = folder("merge");
        std::fs::write(dir.join("pcac.toml"), PCAC_FILE).unwrap();
        std::fs::write(dir.join("rig.toml"), RIG).unwrap();
        let c = ServiceConfig::load_with_controller(&dir.join("rig.toml"), &dir.join("pcac.toml"))
            .unwrap();
        assert!(
            matches!(&c.controller, ControllerConfig::SamplingArm { params } if params.robust_gain == K)
        );
        assert_eq!(c.source.base_dir, dir);
    }

    #[test]
    fn bad_arm_settings_are_refused_naming_the_field() {
        let dir = folder("refused");
        let o = origin(&dir);
        let base = format!("{RIG}{PCAC_FILE}");
        let cases = include_str!("../../../tests/fixtures/refusals/controller-sampling-arm.toml");
        assert_refused_naming_fields(&base, &o, cases);
        // The sample period's refusal names the file and its field.
        let m = params(
            &base.replace("\"robust-gain.toml\"", "\"other-gain.toml\""),
            &o,
        )
        .unwrap_err();
        assert!(
            m.contains("other-gain.toml: field 'robust-gain.sample-period'"),
            "{m}"
        );
        assert!(m.contains("0.001") && m.contains("0.0005"), "{m}");
        let m = params(&base.replace("\"robust-gain.toml\"", "\"nope.toml\""), &o).unwrap_err();
        assert!(m.contains("nope.toml"), "{m}");
        // The arm answers compute-first only.
        let m = ServiceConfig::parse(
            &base.replace("[service]", "[service]\ntiming = \"send-ahead\""),
            &o,
        )
        .unwrap_err()
        .to_string();
        assert!(
            m.contains("service.timing") && m.contains("sampling-arm"),
            "{m}"
        );
    }
}
