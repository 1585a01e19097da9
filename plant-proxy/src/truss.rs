//! # The planar truss of chapter 6 (`kind = "truss"`)
//!
//! A planar truss of pinned members (section 6.2 of the dissertation), turned at load time
//! into the continuous-time generalized plant that [`crate::sim`] discretizes exactly under
//! a zero-order hold, like every other plant kind.
//!
//! ## Equations
//!
//! The structure obeys (6.1), `M q̈ + C q̇ + K q = B u + B_w w`, with `q` the `x` and `y`
//! displacements of the free nodes. Each member `e` from node `a` to node `b`, of length
//! `L`, has in its local coordinates `q̄ = [δx̄_a, δȳ_a, δx̄_b, δȳ_b]` the consistent mass
//! and axial stiffness matrices (6.2),
//!
//! ```text
//!       ρAL ⎡2 0 1 0⎤        EA ⎡ 1 0 −1 0⎤
//! M̄_e = ─── ⎢0 2 0 1⎥,  K̄_e = ── ⎢ 0 0  0 0⎥,
//!        6  ⎢1 0 2 0⎥         L ⎢−1 0  1 0⎥
//!           ⎣0 1 0 2⎦           ⎣ 0 0  0 0⎦
//! ```
//!
//! ([`element_matrices`]). With `(c, s) = (cos θ, sin θ)` the direction of the member
//! from `a` to `b`, the local displacements are `q̄ = T q_e`,
//! `T = diag(R, R)`, `R = [[c, s], [−s, c]]` ([`rotation`]), so the member contributes
//! `Tᵀ M̄_e T` and `Tᵀ K̄_e T` to the global matrices ([`global_element_matrices`]).
//! (`M̄_e` is invariant under the rotation: it is `ρAL/6·[[2I, I], [I, 2I]]`.) The
//! contributions are summed over the members into the rows and columns of the free
//! degrees of freedom; the rows and columns of the boundary nodes (`fixed = true`) are
//! removed. Lumped masses `m_i` add `m_i` to both diagonal entries of node `i`.
//!
//! ## Modes and damping
//!
//! The generalized eigenproblem `K φ = ω² M φ` is solved through the Cholesky factor
//! `M = L Lᵀ`: `S = L⁻¹ K L⁻ᵀ = V Λ Vᵀ` (symmetric), `Φ = L⁻ᵀ V`, so that
//! `Φᵀ M Φ = I` and `Φᵀ K Φ = Λ = diag(ω_i²)` ([`Truss::modes`]). `K` must be positive
//! definite once the boundary nodes are removed (otherwise the truss is a mechanism and is
//! refused). Every mode gets the same damping ratio `ζ` (0.005 in section 6.2): the
//! damping matrix is
//!
//! ```text
//! C = M Φ diag(2 ζ ω_i) Φᵀ M,
//! ```
//!
//! ([`Truss::damping_matrix`]), so that `Φᵀ C Φ = diag(2ζω_i)`. In the modal coordinates `q = Φ η` the model decouples
//! exactly into `η̈_i + 2ζω_i η̇_i + ω_i² η_i = φ_iᵀ (B u + B_w w)`, which is the `modal`
//! plant kind ([`crate::lti::GeneralizedPlant::from_modes`]): the state is
//! `[η_1, η̇_1, η_2, η̇_2, …]`, modes in ascending frequency, and the model is the same
//! linear system as `[[0, I], [−M⁻¹K, −M⁻¹C]]` in physical coordinates (a test checks the
//! frequency responses agree).
//!
//! ## Inputs and outputs
//!
//! Actuators (`u`) and disturbance inputs (`w`) are point forces in N on a node in `x` or
//! `y`: column `j` of `B` is the unit vector of that degree of freedom, so
//! `b_{u,i,j} = φ_i[dof_j]`. A sensor is a displacement in `x` or `y` times a gain:
//! `y_k = g_k δ_{dof_k}`, `c_{y,i,k} = g_k φ_i[dof_k]`; the performance outputs `z` are
//! declared the same way (without noise unless `[plant.noise] z-std` says otherwise).
//!
//! ## Measurement noise from a signal-to-noise ratio
//!
//! Section 6.2 states the noise as "a sensor measuring a 0.1-Hz disturbance at node 8 has
//! a signal-to-noise ratio of 40 dB". With `[plant.truss.noise-snr]` the standard deviation
//! of the white noise on every `y` is computed from the model ([`snr_noise_std`]):
//!
//! ```text
//! σ = (a |G_{y_s, w_d}(j 2π f)| / √2) / 10^(SNR/20),
//! ```
//!
//! the RMS of sensor `s`'s steady response to the tone `a sin(2π f t)` on disturbance
//! input `d`, divided by the amplitude ratio of the SNR (100 for 40 dB). `G` includes the
//! sensor gain. Here `G_{y_s,w_d}(jω) = Σ_i c_{y,i,s} b_{w,i,d} / (ω_i² − ω² + 2jζω_iω)`.
//!
//! ## The file
//!
//! ```toml
//! [plant]
//! kind = "truss"
//! inputs = 2                   # = number of actuators
//! disturbances = 1             # = number of disturbance-inputs
//! outputs-y = 4                # = number of sensors-y
//! outputs-z = 4                # = number of sensors-z
//!
//! [plant.truss]
//! youngs-modulus = 1.0e11      # E, Pa
//! area = 5.0e-4                # A, m²
//! density = 1700.0             # ρ, kg/m³
//! damping = 0.005              # ζ of every mode
//! nodes = [ { name = "B1", x = 0.0, y = 0.0, fixed = true },
//!           { name = "1", x = 0.0, y = 45.0, mass = 1.0 }, … ]   # m, kg (mass default 0)
//! members = [ ["B1", "1"], … ]                                   # pinned members
//! actuators = [ { node = "3", direction = "x" }, … ]             # forces u, N
//! disturbance-inputs = [ { node = "1", direction = "x" } ]       # forces w, N
//! sensors-y = [ { node = "5", direction = "x", gain = 10.0 }, … ] # gain default 1
//! sensors-z = [ … ]
//!
//! [plant.truss.noise-snr]      # optional: sets [plant.noise] y-std (then not given there)
//! db = 40.0
//! frequency-hz = 0.1
//! amplitude = 1.0              # default 1
//! disturbance = 0              # index into disturbance-inputs (default 0)
//! sensor = 3                   # index into sensors-y
//! ```

use crate::lti::{ChannelDims, GeneralizedPlant, Mode};
use nalgebra::{Cholesky, Complex, DMatrix, Matrix4, SymmetricEigen};
use serde::Deserialize;
use std::collections::HashMap;
use std::f64::consts::PI;
use std::fmt;

/// Why a `[plant.truss]` table was refused: the field (dotted path below `plant.truss`,
/// or `plant.<count>`) and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct TrussError {
    /// Dotted path of the field, e.g. `plant.truss.members[3]`.
    pub field: String,
    /// What is wrong.
    pub problem: String,
}

impl TrussError {
    fn new(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            problem: problem.into(),
        }
    }
}

impl fmt::Display for TrussError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "field '{}': {}", self.field, self.problem)
    }
}

impl std::error::Error for TrussError {}

/// A direction of a force or a displacement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Global `x`.
    X,
    /// Global `y`.
    Y,
}

/// One node of the truss.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Name used by members, actuators and sensors (e.g. `"1"` … `"8"`, `"B1"`).
    pub name: String,
    /// Position `x`, m.
    pub x: f64,
    /// Position `y`, m.
    pub y: f64,
    /// Lumped mass at the node, kg (in both directions).
    pub mass: f64,
    /// A boundary node: both displacements are zero and its rows are removed.
    pub fixed: bool,
}

/// A point force or a sensed displacement at a node, in one direction, with a gain
/// (1 for forces).
#[derive(Debug, Clone, PartialEq)]
pub struct Port {
    /// Index of the node in [`Truss::nodes`].
    pub node: usize,
    /// Direction.
    pub direction: Direction,
    /// Gain: output per metre for a sensor, 1 for a force.
    pub gain: f64,
}

/// The SNR definition of the measurement noise (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseSnr {
    /// Signal-to-noise ratio, dB (power ratio `10^(db/10)`).
    pub db: f64,
    /// Frequency of the reference tone, Hz.
    pub frequency_hz: f64,
    /// Amplitude of the reference tone on the disturbance input.
    pub amplitude: f64,
    /// Index of the disturbance input that carries the tone.
    pub disturbance: usize,
    /// Index of the measurement (`sensors-y`) whose response is the signal.
    pub sensor: usize,
}

/// A validated truss: geometry, material, ports.
#[derive(Debug, Clone, PartialEq)]
pub struct Truss {
    /// Elastic modulus `E`, Pa.
    pub youngs_modulus: f64,
    /// Cross-section area `A`, m².
    pub area: f64,
    /// Density `ρ`, kg/m³.
    pub density: f64,
    /// Damping ratio `ζ` of every mode.
    pub damping: f64,
    /// Nodes (boundary and free).
    pub nodes: Vec<Node>,
    /// Members as pairs of node indices.
    pub members: Vec<(usize, usize)>,
    /// Control forces `u`.
    pub actuators: Vec<Port>,
    /// Disturbance forces `w`.
    pub disturbances: Vec<Port>,
    /// Measurements `y`.
    pub sensors_y: Vec<Port>,
    /// Performance outputs `z`.
    pub sensors_z: Vec<Port>,
    /// Optional SNR definition of the noise on `y`.
    pub noise_snr: Option<NoiseSnr>,
}

/// The mass-normalized modes of a truss: `Φᵀ M Φ = I`, `Φᵀ K Φ = diag(ω²)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Modes {
    /// Natural frequencies `ω_i`, rad/s, ascending.
    pub omega: Vec<f64>,
    /// Mode shapes as columns (`n_dof × n_dof`).
    pub phi: DMatrix<f64>,
}

impl Modes {
    /// Natural frequencies in Hz, ascending.
    pub fn frequencies_hz(&self) -> Vec<f64> {
        self.omega.iter().map(|w| w / (2.0 * PI)).collect()
    }
}

/// The local matrices (6.2) of a member of length `l`: `(M̄, K̄)`, local coordinates
/// `[δx̄_1, δȳ_1, δx̄_2, δȳ_2]`.
pub fn element_matrices(e: f64, a: f64, rho: f64, l: f64) -> (Matrix4<f64>, Matrix4<f64>) {
    let m = rho * a * l / 6.0;
    let k = e * a / l;
    #[rustfmt::skip]
    let mbar = Matrix4::new(
        2.0, 0.0, 1.0, 0.0,
        0.0, 2.0, 0.0, 1.0,
        1.0, 0.0, 2.0, 0.0,
        0.0, 1.0, 0.0, 2.0,
    ) * m;
    #[rustfmt::skip]
    let kbar = Matrix4::new(
         1.0, 0.0, -1.0, 0.0,
         0.0, 0.0,  0.0, 0.0,
        -1.0, 0.0,  1.0, 0.0,
         0.0, 0.0,  0.0, 0.0,
    ) * k;
    (mbar, kbar)
}

/// The transformation `T = diag(R, R)`, `R = [[c, s], [−s, c]]`, from global to local
/// displacements of a member whose axis has direction `(c, s) = (cos θ, sin θ)`.
pub fn rotation(c: f64, s: f64) -> Matrix4<f64> {
    #[rustfmt::skip]
    let t = Matrix4::new(
          c,   s, 0.0, 0.0,
         -s,   c, 0.0, 0.0,
        0.0, 0.0,   c,   s,
        0.0, 0.0,  -s,   c,
    );
    t
}

/// The global matrices `(Tᵀ M̄ T, Tᵀ K̄ T)` of a member from `(x1, y1)` to `(x2, y2)`,
/// global coordinates `[δx_1, δy_1, δx_2, δy_2]`.
pub fn global_element_matrices(
    e: f64,
    a: f64,
    rho: f64,
    p1: (f64, f64),
    p2: (f64, f64),
) -> (Matrix4<f64>, Matrix4<f64>) {
    let (dx, dy) = (p2.0 - p1.0, p2.1 - p1.1);
    let l = dx.hypot(dy);
    let (mbar, kbar) = element_matrices(e, a, rho, l);
    let t = rotation(dx / l, dy / l);
    (t.transpose() * mbar * t, t.transpose() * kbar * t)
}

impl Truss {
    /// Index of each free node's `x` degree of freedom (its `y` follows), `None` for a
    /// boundary node. Free nodes are numbered in file order.
    pub fn dof_map(&self) -> Vec<Option<usize>> {
        let mut next = 0;
        self.nodes
            .iter()
            .map(|n| {
                if n.fixed {
                    None
                } else {
                    next += 2;
                    Some(next - 2)
                }
            })
            .collect()
    }

    /// Number of degrees of freedom (two per free node).
    pub fn n_dof(&self) -> usize {
        2 * self.nodes.iter().filter(|n| !n.fixed).count()
    }

    /// The degree of freedom of a port (the port's node must be free).
    pub fn port_dof(&self, p: &Port) -> usize {
        let base = self.dof_map()[p.node].expect("ports are on free nodes");
        base + if p.direction == Direction::Y { 1 } else { 0 }
    }

    /// Global `(M, K)` of the free degrees of freedom: the members' `Tᵀ M̄ T`, `Tᵀ K̄ T`
    /// summed, boundary rows and columns removed, lumped masses added.
    pub fn assemble(&self) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = self.n_dof();
        let map = self.dof_map();
        let mut m = DMatrix::zeros(n, n);
        let mut k = DMatrix::zeros(n, n);
        for &(a, b) in &self.members {
            let (na, nb) = (&self.nodes[a], &self.nodes[b]);
            let (me, ke) = global_element_matrices(
                self.youngs_modulus,
                self.area,
                self.density,
                (na.x, na.y),
                (nb.x, nb.y),
            );
            let dofs = [map[a], map[a].map(|d| d + 1), map[b], map[b].map(|d| d + 1)];
            for (i, di) in dofs.iter().enumerate() {
                let Some(di) = *di else { continue };
                for (j, dj) in dofs.iter().enumerate() {
                    let Some(dj) = *dj else { continue };
                    m[(di, dj)] += me[(i, j)];
                    k[(di, dj)] += ke[(i, j)];
                }
            }
        }
        for (node, d) in self.nodes.iter().zip(&map) {
            if let Some(d) = *d {
                m[(d, d)] += node.mass;
                m[(d + 1, d + 1)] += node.mass;
            }
        }
        (m, k)
    }

    /// The mass-normalized modes (see the module documentation). Fails when `M` or `K`
    /// is not positive definite (a mechanism, or a node without mass or member).
    pub fn modes(&self) -> Result<Modes, String> {
        let (m, k) = self.assemble();
        let n = m.nrows();
        let chol = Cholesky::new(m).ok_or("the mass matrix is not positive definite")?;
        let l = chol.l();
        // S = L⁻¹ K L⁻ᵀ.
        let lk = l
            .solve_lower_triangular(&k)
            .ok_or("the Cholesky factor of M is singular")?;
        let s = l
            .solve_lower_triangular(&lk.transpose())
            .ok_or("the Cholesky factor of M is singular")?;
        let s = (&s + s.transpose()) * 0.5;
        let eig = SymmetricEigen::new(s);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
        let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        if let Some(&i) = order.first() {
            let l0 = eig.eigenvalues[i];
            if l0.is_nan() || l0 <= 1e-12 * lmax {
                return Err(format!(
                    "the stiffness matrix is not positive definite once the boundary nodes \
                     are removed (smallest ω² = {l0:.3e}): the truss is a mechanism"
                ));
            }
        }
        let mut v = DMatrix::zeros(n, n);
        for (c, &i) in order.iter().enumerate() {
            v.set_column(c, &eig.eigenvectors.column(i));
        }
        let phi = l
            .transpose()
            .solve_upper_triangular(&v)
            .ok_or("the Cholesky factor of M is singular")?;
        let omega = order.iter().map(|&i| eig.eigenvalues[i].sqrt()).collect();
        Ok(Modes { omega, phi })
    }

    /// The damping matrix `C = M Φ diag(2ζω_i) Φᵀ M`.
    pub fn damping_matrix(&self, modes: &Modes) -> DMatrix<f64> {
        let (m, _) = self.assemble();
        let d = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
            modes.omega.len(),
            modes.omega.iter().map(|w| 2.0 * self.damping * w),
        ));
        let mp = &m * &modes.phi;
        &mp * d * mp.transpose()
    }

    /// The channel counts of the ports.
    pub fn dims(&self) -> ChannelDims {
        ChannelDims {
            n_u: self.actuators.len(),
            n_w: self.disturbances.len(),
            n_y: self.sensors_y.len(),
            n_z: self.sensors_z.len(),
        }
    }

    /// The modal data of the plant: one [`Mode`] per structural mode (ascending
    /// frequency), participations `φ_i[dof]` and sensor gains `g φ_i[dof]`.
    pub fn plant_modes(&self, modes: &Modes) -> Vec<Mode> {
        let pick = |ports: &[Port], i: usize| -> Vec<f64> {
            ports
                .iter()
                .map(|p| p.gain * modes.phi[(self.port_dof(p), i)])
                .collect()
        };
        (0..modes.omega.len())
            .map(|i| Mode {
                omega: modes.omega[i],
                zeta: self.damping,
                b_u: pick(&self.actuators, i),
                b_w: pick(&self.disturbances, i),
                c_y: pick(&self.sensors_y, i),
                c_y_vel: vec![0.0; self.sensors_y.len()],
                c_z: pick(&self.sensors_z, i),
                c_z_vel: vec![0.0; self.sensors_z.len()],
            })
            .collect()
    }

    /// The continuous-time generalized plant in modal coordinates (state
    /// `[η_1, η̇_1, …]`).
    pub fn plant(&self) -> Result<(GeneralizedPlant, Modes), String> {
        let modes = self.modes()?;
        let p = GeneralizedPlant::from_modes(&self.plant_modes(&modes), self.dims())
            .map_err(|e| e.to_string())?;
        Ok((p, modes))
    }

    /// The same plant in physical coordinates, state `[q; q̇]`:
    /// `A = [[0, I], [−M⁻¹K, −M⁻¹C]]`, `B_u = [0; M⁻¹B]`, `C_y = [G_y, 0]` (a reference for
    /// tests and for users who want the physical state).
    pub fn physical_plant(&self) -> Result<GeneralizedPlant, String> {
        let modes = self.modes()?;
        let (m, k) = self.assemble();
        let c = self.damping_matrix(&modes);
        let n = m.nrows();
        let minv = m
            .clone()
            .cholesky()
            .ok_or("the mass matrix is not positive definite")?
            .inverse();
        let mut p = GeneralizedPlant::zeros(2 * n, self.dims());
        p.a.view_mut((0, n), (n, n))
            .copy_from(&DMatrix::identity(n, n));
        p.a.view_mut((n, 0), (n, n)).copy_from(&(-(&minv * &k)));
        p.a.view_mut((n, n), (n, n)).copy_from(&(-(&minv * &c)));
        let forces = |ports: &[Port]| {
            let mut b = DMatrix::zeros(n, ports.len());
            for (j, port) in ports.iter().enumerate() {
                b[(self.port_dof(port), j)] = port.gain;
            }
            &minv * b
        };
        p.b_u
            .view_mut((n, 0), (n, self.actuators.len()))
            .copy_from(&forces(&self.actuators));
        p.b_w
            .view_mut((n, 0), (n, self.disturbances.len()))
            .copy_from(&forces(&self.disturbances));
        for (i, s) in self.sensors_y.iter().enumerate() {
            p.c_y[(i, self.port_dof(s))] = s.gain;
        }
        for (i, s) in self.sensors_z.iter().enumerate() {
            p.c_z[(i, self.port_dof(s))] = s.gain;
        }
        Ok(p)
    }
}

/// `G_{y_s, w_d}(jω)` of the modal plant: `Σ_i c_{y,i,s} b_{w,i,d} / (ω_i² − ω² + 2jζ_iω_iω)`.
pub fn modal_response(
    modes: &[Mode],
    sensor: usize,
    disturbance: usize,
    omega: f64,
) -> Complex<f64> {
    modes
        .iter()
        .map(|m| {
            let den = Complex::new(
                m.omega * m.omega - omega * omega,
                2.0 * m.zeta * m.omega * omega,
            );
            Complex::new(m.c_y[sensor] * m.b_w[disturbance], 0.0) / den
        })
        .sum()
}

/// The standard deviation of the white noise on `y` given by an SNR (see the module
/// documentation): `σ = a |G_{y_s,w_d}(j2πf)| / √2 / 10^(db/20)`.
pub fn snr_noise_std(modes: &[Mode], snr: &NoiseSnr) -> f64 {
    let g = modal_response(
        modes,
        snr.sensor,
        snr.disturbance,
        2.0 * PI * snr.frequency_hz,
    );
    snr.amplitude * g.norm() / 2f64.sqrt() / 10f64.powf(snr.db / 20.0)
}

/// A truss read from a scenario: the validated truss, its continuous plant, its modes and
/// the noise level its SNR gives (if any).
#[derive(Debug, Clone, PartialEq)]
pub struct TrussPlant {
    /// The validated truss.
    pub truss: Truss,
    /// The continuous plant in modal coordinates.
    pub model: GeneralizedPlant,
    /// Its modes.
    pub modes: Modes,
    /// `σ` of the white noise on every `y` from `[plant.truss.noise-snr]`.
    pub y_noise_std: Option<f64>,
}

// ---------------------------------------------------------------------------------------
// The `[plant.truss]` table.

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawTruss {
    youngs_modulus: Option<f64>,
    area: Option<f64>,
    density: Option<f64>,
    damping: Option<f64>,
    nodes: Option<Vec<RawNode>>,
    members: Option<Vec<Vec<String>>>,
    actuators: Option<Vec<RawPort>>,
    disturbance_inputs: Option<Vec<RawPort>>,
    sensors_y: Option<Vec<RawPort>>,
    sensors_z: Option<Vec<RawPort>>,
    noise_snr: Option<RawSnr>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNode {
    name: Option<String>,
    x: Option<f64>,
    y: Option<f64>,
    mass: Option<f64>,
    fixed: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPort {
    node: Option<String>,
    direction: Option<String>,
    gain: Option<f64>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawSnr {
    db: Option<f64>,
    frequency_hz: Option<f64>,
    amplitude: Option<f64>,
    disturbance: Option<usize>,
    sensor: Option<usize>,
}

const T: &str = "plant.truss";

fn req<V>(v: Option<V>, field: &str) -> Result<V, TrussError> {
    v.ok_or_else(|| TrussError::new(field, "is missing"))
}

fn positive(v: f64, field: &str) -> Result<f64, TrussError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(TrussError::new(
            field,
            format!("{v} is not positive and finite"),
        ))
    }
}

fn non_negative(v: f64, field: &str) -> Result<f64, TrussError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(TrussError::new(
            field,
            format!("{v} is not non-negative and finite"),
        ))
    }
}

/// Reads and validates the `[plant.truss]` table against the channel counts of
/// `[plant]`, assembles the truss and computes its modes, plant and noise level.
pub fn from_toml(value: &toml::Value, dims: ChannelDims) -> Result<TrussPlant, TrussError> {
    let raw: RawTruss = value
        .clone()
        .try_into()
        .map_err(|e: toml::de::Error| TrussError::new(T, e.message().to_string()))?;
    let f = |k: &str| format!("{T}.{k}");
    let youngs_modulus = positive(
        req(raw.youngs_modulus, &f("youngs-modulus"))?,
        &f("youngs-modulus"),
    )?;
    let area = positive(req(raw.area, &f("area"))?, &f("area"))?;
    let density = non_negative(req(raw.density, &f("density"))?, &f("density"))?;
    let damping = non_negative(req(raw.damping, &f("damping"))?, &f("damping"))?;

    let raw_nodes = req(raw.nodes, &f("nodes"))?;
    let mut nodes = Vec::with_capacity(raw_nodes.len());
    let mut by_name = HashMap::new();
    for (i, n) in raw_nodes.into_iter().enumerate() {
        let nf = |k: &str| format!("{T}.nodes[{i}].{k}");
        let name = req(n.name, &nf("name"))?;
        if by_name.insert(name.clone(), i).is_some() {
            return Err(TrussError::new(
                nf("name"),
                format!("'{name}' is used twice"),
            ));
        }
        let x = req(n.x, &nf("x"))?;
        let y = req(n.y, &nf("y"))?;
        if !(x.is_finite() && y.is_finite()) {
            return Err(TrussError::new(nf("x"), "the position is not finite"));
        }
        let mass = non_negative(n.mass.unwrap_or(0.0), &nf("mass"))?;
        nodes.push(Node {
            name,
            x,
            y,
            mass,
            fixed: n.fixed.unwrap_or(false),
        });
    }
    let node = |name: &str, field: &str| -> Result<usize, TrussError> {
        by_name
            .get(name)
            .copied()
            .ok_or_else(|| TrussError::new(field, format!("no node is named '{name}'")))
    };

    let raw_members = req(raw.members, &f("members"))?;
    let mut members = Vec::with_capacity(raw_members.len());
    for (i, m) in raw_members.iter().enumerate() {
        let mf = format!("{T}.members[{i}]");
        let [a, b] = m.as_slice() else {
            return Err(TrussError::new(mf, "a member is a pair of node names"));
        };
        let (a, b) = (node(a, &mf)?, node(b, &mf)?);
        let (na, nb) = (&nodes[a], &nodes[b]);
        if (nb.x - na.x).hypot(nb.y - na.y) <= 0.0 {
            return Err(TrussError::new(mf, "the member has zero length"));
        }
        members.push((a, b));
    }

    let ports = |v: Option<Vec<RawPort>>,
                 key: &str,
                 count: usize,
                 count_field: &str,
                 sensor: bool|
     -> Result<Vec<Port>, TrussError> {
        let v = v.unwrap_or_default();
        if v.len() != count {
            return Err(TrussError::new(
                f(key),
                format!("has {} entries, {count_field} = {count}", v.len()),
            ));
        }
        v.into_iter()
            .enumerate()
            .map(|(i, p)| {
                let pf = |k: &str| format!("{T}.{key}[{i}].{k}");
                let n = node(&req(p.node, &pf("node"))?, &pf("node"))?;
                if nodes[n].fixed {
                    return Err(TrussError::new(
                        pf("node"),
                        "is a boundary node (fixed = true)",
                    ));
                }
                let direction = match req(p.direction, &pf("direction"))?.as_str() {
                    "x" => Direction::X,
                    "y" => Direction::Y,
                    other => {
                        return Err(TrussError::new(
                            pf("direction"),
                            format!("'{other}' is not \"x\" or \"y\""),
                        ));
                    }
                };
                let gain = match p.gain {
                    Some(_) if !sensor => {
                        return Err(TrussError::new(pf("gain"), "forces have no gain"));
                    }
                    Some(g) if g.is_finite() => g,
                    Some(g) => {
                        return Err(TrussError::new(pf("gain"), format!("{g} is not finite")));
                    }
                    None => 1.0,
                };
                Ok(Port {
                    node: n,
                    direction,
                    gain,
                })
            })
            .collect()
    };
    let actuators = ports(raw.actuators, "actuators", dims.n_u, "plant.inputs", false)?;
    let disturbances = ports(
        raw.disturbance_inputs,
        "disturbance-inputs",
        dims.n_w,
        "plant.disturbances",
        false,
    )?;
    let sensors_y = ports(
        raw.sensors_y,
        "sensors-y",
        dims.n_y,
        "plant.outputs-y",
        true,
    )?;
    let sensors_z = ports(
        raw.sensors_z,
        "sensors-z",
        dims.n_z,
        "plant.outputs-z",
        true,
    )?;

    let noise_snr = match raw.noise_snr {
        None => None,
        Some(s) => {
            let sf = |k: &str| format!("{T}.noise-snr.{k}");
            let db = req(s.db, &sf("db"))?;
            if !db.is_finite() {
                return Err(TrussError::new(sf("db"), format!("{db} is not finite")));
            }
            let frequency_hz = non_negative(
                req(s.frequency_hz, &sf("frequency-hz"))?,
                &sf("frequency-hz"),
            )?;
            let amplitude = non_negative(s.amplitude.unwrap_or(1.0), &sf("amplitude"))?;
            let disturbance = s.disturbance.unwrap_or(0);
            if disturbance >= dims.n_w {
                return Err(TrussError::new(
                    sf("disturbance"),
                    format!(
                        "{disturbance} is not a disturbance input (there are {})",
                        dims.n_w
                    ),
                ));
            }
            let sensor = req(s.sensor, &sf("sensor"))?;
            if sensor >= dims.n_y {
                return Err(TrussError::new(
                    sf("sensor"),
                    format!("{sensor} is not a measurement (there are {})", dims.n_y),
                ));
            }
            Some(NoiseSnr {
                db,
                frequency_hz,
                amplitude,
                disturbance,
                sensor,
            })
        }
    };

    let truss = Truss {
        youngs_modulus,
        area,
        density,
        damping,
        nodes,
        members,
        actuators,
        disturbances,
        sensors_y,
        sensors_z,
        noise_snr,
    };
    if truss.n_dof() == 0 {
        return Err(TrussError::new(f("nodes"), "every node is fixed"));
    }
    let (model, modes) = truss.plant().map_err(|e| TrussError::new(T, e))?;
    let y_noise_std = truss
        .noise_snr
        .as_ref()
        .map(|s| snr_noise_std(&truss.plant_modes(&modes), s));
    Ok(TrussPlant {
        truss,
        model,
        modes,
        y_noise_std,
    })
}

#[cfg(test)]
mod tests;
