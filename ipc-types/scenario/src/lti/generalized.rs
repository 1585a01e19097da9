//! # The generalized plant of Figure 3.1
//!
//! The plant with control inputs `u`, disturbance inputs `w`, measurements `y` and
//! performance outputs `z`, in continuous time:
//!
//! ```text
//! ẋ = A x + B_u u + B_w w,
//! y = C_y x + D_yu u + D_yw w,
//! z = C_z x + D_zu u + D_zw w,
//! ```
//!
//! built from one of three descriptions:
//!
//! - the four transfer-function matrices `G_yu, G_yw, G_zu, G_zw`
//!   ([`GeneralizedPlant::from_tf_blocks`]): the block matrix `[[G_yu, G_yw], [G_zu, G_zw]]`
//!   is realized column-wise by [`super::realize_tf_matrix_sized`], so the states are those
//!   of that realization (`u` columns first, then `w` columns);
//! - the matrices themselves ([`GeneralizedPlant::validate`] checks them);
//! - modes ([`GeneralizedPlant::from_modes`]): each mode `r` obeys
//!   `q̈_r + 2 ζ_r ω_r q̇_r + ω_r² q_r = b_{u,r}·u + b_{w,r}·w` and the outputs are
//!   `y = Σ_r (c_{y,r} q_r + c^{vel}_{y,r} q̇_r)`, `z` likewise; the state is
//!   `[q_1, q̇_1, q_2, q̇_2, …]` and each mode contributes the block
//!   `[[0, 1], [−ω_r², −2 ζ_r ω_r]]` to `A`.

use super::{LtiError, StateSpace, Tf, realize_tf_matrix_sized};
use nalgebra::DMatrix;

/// Numbers of channels of a generalized plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelDims {
    /// Control inputs `u`.
    pub n_u: usize,
    /// Disturbance inputs `w`.
    pub n_w: usize,
    /// Measurements `y`.
    pub n_y: usize,
    /// Performance outputs `z`.
    pub n_z: usize,
}

/// The continuous-time generalized plant (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct GeneralizedPlant {
    /// `A`, `n_x × n_x`.
    pub a: DMatrix<f64>,
    /// `B_u`, `n_x × n_u`.
    pub b_u: DMatrix<f64>,
    /// `B_w`, `n_x × n_w`.
    pub b_w: DMatrix<f64>,
    /// `C_y`, `n_y × n_x`.
    pub c_y: DMatrix<f64>,
    /// `C_z`, `n_z × n_x`.
    pub c_z: DMatrix<f64>,
    /// `D_yu`, `n_y × n_u`.
    pub d_yu: DMatrix<f64>,
    /// `D_yw`, `n_y × n_w`.
    pub d_yw: DMatrix<f64>,
    /// `D_zu`, `n_z × n_u`.
    pub d_zu: DMatrix<f64>,
    /// `D_zw`, `n_z × n_w`.
    pub d_zw: DMatrix<f64>,
}

/// One lightly damped mode of a modal model (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Mode {
    /// Natural frequency `ω`, rad/s (≥ 0).
    pub omega: f64,
    /// Damping ratio `ζ` (≥ 0).
    pub zeta: f64,
    /// Participation of each control input, `n_u` entries.
    pub b_u: Vec<f64>,
    /// Participation of each disturbance input, `n_w` entries.
    pub b_w: Vec<f64>,
    /// Displacement gain to each measurement, `n_y` entries.
    pub c_y: Vec<f64>,
    /// Velocity gain to each measurement, `n_y` entries.
    pub c_y_vel: Vec<f64>,
    /// Displacement gain to each performance output, `n_z` entries.
    pub c_z: Vec<f64>,
    /// Velocity gain to each performance output, `n_z` entries.
    pub c_z_vel: Vec<f64>,
}

impl GeneralizedPlant {
    /// A plant with all matrices zero.
    pub fn zeros(n_x: usize, dims: ChannelDims) -> Self {
        let ChannelDims { n_u, n_w, n_y, n_z } = dims;
        Self {
            a: DMatrix::zeros(n_x, n_x),
            b_u: DMatrix::zeros(n_x, n_u),
            b_w: DMatrix::zeros(n_x, n_w),
            c_y: DMatrix::zeros(n_y, n_x),
            c_z: DMatrix::zeros(n_z, n_x),
            d_yu: DMatrix::zeros(n_y, n_u),
            d_yw: DMatrix::zeros(n_y, n_w),
            d_zu: DMatrix::zeros(n_z, n_u),
            d_zw: DMatrix::zeros(n_z, n_w),
        }
    }

    /// Checks that the dimensions agree (dimensions taken from `A`, `B_u`, `B_w`, `C_y`,
    /// `C_z`) and that every entry is finite.
    pub fn validate(&self) -> Result<(), LtiError> {
        let dims = self.dims();
        let n = self.n_x();
        let checks: [(&str, &DMatrix<f64>, usize, usize); 9] = [
            ("A", &self.a, n, n),
            ("B_u", &self.b_u, n, dims.n_u),
            ("B_w", &self.b_w, n, dims.n_w),
            ("C_y", &self.c_y, dims.n_y, n),
            ("C_z", &self.c_z, dims.n_z, n),
            ("D_yu", &self.d_yu, dims.n_y, dims.n_u),
            ("D_yw", &self.d_yw, dims.n_y, dims.n_w),
            ("D_zu", &self.d_zu, dims.n_z, dims.n_u),
            ("D_zw", &self.d_zw, dims.n_z, dims.n_w),
        ];
        for (what, m, r, c) in checks {
            super::check_dims(what, m, r, c)?;
        }
        Ok(())
    }

    /// Number of states `n_x`.
    pub fn n_x(&self) -> usize {
        self.a.nrows()
    }

    /// The channel counts `(n_u, n_w, n_y, n_z)`.
    pub fn dims(&self) -> ChannelDims {
        ChannelDims {
            n_u: self.b_u.ncols(),
            n_w: self.b_w.ncols(),
            n_y: self.c_y.nrows(),
            n_z: self.c_z.nrows(),
        }
    }

    /// The plant as one state-space model with inputs `[u; w]` and outputs `[y; z]`.
    pub fn state_space(&self) -> StateSpace {
        let ChannelDims { n_u, n_w, n_y, n_z } = self.dims();
        let n = self.n_x();
        let mut b = DMatrix::zeros(n, n_u + n_w);
        b.view_mut((0, 0), (n, n_u)).copy_from(&self.b_u);
        b.view_mut((0, n_u), (n, n_w)).copy_from(&self.b_w);
        let mut c = DMatrix::zeros(n_y + n_z, n);
        c.view_mut((0, 0), (n_y, n)).copy_from(&self.c_y);
        c.view_mut((n_y, 0), (n_z, n)).copy_from(&self.c_z);
        let mut d = DMatrix::zeros(n_y + n_z, n_u + n_w);
        d.view_mut((0, 0), (n_y, n_u)).copy_from(&self.d_yu);
        d.view_mut((0, n_u), (n_y, n_w)).copy_from(&self.d_yw);
        d.view_mut((n_y, 0), (n_z, n_u)).copy_from(&self.d_zu);
        d.view_mut((n_y, n_u), (n_z, n_w)).copy_from(&self.d_zw);
        StateSpace {
            a: self.a.clone(),
            b,
            c,
            d,
        }
    }

    /// Realizes the four transfer-function matrices (rows = outputs, columns = inputs,
    /// `None` = zero; rows missing at the end are zero) as one plant, column-wise (see the
    /// module documentation).
    pub fn from_tf_blocks(
        yu: &[Vec<Option<Tf>>],
        yw: &[Vec<Option<Tf>>],
        zu: &[Vec<Option<Tf>>],
        zw: &[Vec<Option<Tf>>],
        dims: ChannelDims,
    ) -> Result<Self, LtiError> {
        let ChannelDims { n_u, n_w, n_y, n_z } = dims;
        let blocks = [
            ("G_yu", yu, n_y, n_u),
            ("G_yw", yw, n_y, n_w),
            ("G_zu", zu, n_z, n_u),
            ("G_zw", zw, n_z, n_w),
        ];
        for (what, g, rows, cols) in blocks {
            let bad_row = g.iter().position(|r| r.len() != cols);
            if g.len() > rows || bad_row.is_some() {
                return Err(LtiError::Dimension {
                    what: what.to_string(),
                    expected: (rows, cols),
                    found: (g.len(), bad_row.map_or(cols, |i| g[i].len())),
                });
            }
        }
        let row = |g: &[Vec<Option<Tf>>], i: usize, cols: usize| -> Vec<Option<Tf>> {
            g.get(i).cloned().unwrap_or_else(|| vec![None; cols])
        };
        let mut m: Vec<Vec<Option<Tf>>> = Vec::with_capacity(n_y + n_z);
        for i in 0..n_y {
            let mut r = row(yu, i, n_u);
            r.extend(row(yw, i, n_w));
            m.push(r);
        }
        for i in 0..n_z {
            let mut r = row(zu, i, n_u);
            r.extend(row(zw, i, n_w));
            m.push(r);
        }
        let ss = realize_tf_matrix_sized(&m, n_y + n_z, n_u + n_w)?;
        let n = ss.n_states();
        Ok(Self {
            b_u: ss.b.view((0, 0), (n, n_u)).into_owned(),
            b_w: ss.b.view((0, n_u), (n, n_w)).into_owned(),
            c_y: ss.c.view((0, 0), (n_y, n)).into_owned(),
            c_z: ss.c.view((n_y, 0), (n_z, n)).into_owned(),
            d_yu: ss.d.view((0, 0), (n_y, n_u)).into_owned(),
            d_yw: ss.d.view((0, n_u), (n_y, n_w)).into_owned(),
            d_zu: ss.d.view((n_y, 0), (n_z, n_u)).into_owned(),
            d_zw: ss.d.view((n_y, n_u), (n_z, n_w)).into_owned(),
            a: ss.a,
        })
    }

    /// The modal model of `modes` (see the module documentation); every vector of every
    /// mode must have the length of its channel count.
    pub fn from_modes(modes: &[Mode], dims: ChannelDims) -> Result<Self, LtiError> {
        let ChannelDims { n_u, n_w, n_y, n_z } = dims;
        let mut p = Self::zeros(2 * modes.len(), dims);
        for (r, mode) in modes.iter().enumerate() {
            let what = |v: &str| format!("mode {r} {v}");
            let vectors: [(&str, &Vec<f64>, usize); 6] = [
                ("b_u", &mode.b_u, n_u),
                ("b_w", &mode.b_w, n_w),
                ("c_y", &mode.c_y, n_y),
                ("c_y_vel", &mode.c_y_vel, n_y),
                ("c_z", &mode.c_z, n_z),
                ("c_z_vel", &mode.c_z_vel, n_z),
            ];
            for (name, v, len) in vectors {
                if v.len() != len {
                    return Err(LtiError::Dimension {
                        what: what(name),
                        expected: (1, len),
                        found: (1, v.len()),
                    });
                }
                super::check_finite(&what(name), v)?;
            }
            if !(mode.omega.is_finite() && mode.omega >= 0.0) {
                return Err(LtiError::NonFinite {
                    what: what("frequency (must be ≥ 0)"),
                });
            }
            if !(mode.zeta.is_finite() && mode.zeta >= 0.0) {
                return Err(LtiError::NonFinite {
                    what: what("damping (must be ≥ 0)"),
                });
            }
            let (q, v) = (2 * r, 2 * r + 1);
            p.a[(q, v)] = 1.0;
            p.a[(v, q)] = -mode.omega * mode.omega;
            p.a[(v, v)] = -2.0 * mode.zeta * mode.omega;
            for j in 0..n_u {
                p.b_u[(v, j)] = mode.b_u[j];
            }
            for j in 0..n_w {
                p.b_w[(v, j)] = mode.b_w[j];
            }
            for i in 0..n_y {
                p.c_y[(i, q)] = mode.c_y[i];
                p.c_y[(i, v)] = mode.c_y_vel[i];
            }
            for i in 0..n_z {
                p.c_z[(i, q)] = mode.c_z[i];
                p.c_z[(i, v)] = mode.c_z_vel[i];
            }
        }
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Complex;

    #[test]
    fn tf_blocks_are_realized_into_the_four_channels() {
        let g = Tf::new(vec![2.0, 1.0], vec![1.0, 0.4, 4.0]).unwrap();
        let h = Tf::new(vec![1.0], vec![1.0, 3.0]).unwrap();
        let dims = ChannelDims {
            n_u: 1,
            n_w: 1,
            n_y: 1,
            n_z: 1,
        };
        let p = GeneralizedPlant::from_tf_blocks(
            &[vec![Some(g.clone())]],
            &[vec![Some(h.clone())]],
            &[vec![Some(g.clone())]],
            &[], // G_zw = 0
            dims,
        )
        .unwrap();
        p.validate().unwrap();
        // u column: shared denominator (2 states); w column: 1 state.
        assert_eq!(p.n_x(), 3);
        let s = Complex::new(0.1, 1.3);
        let resp = p.state_space().freq_response(s).unwrap();
        assert!((resp[(0, 0)] - g.eval(s)).norm() < 1e-13);
        assert!((resp[(0, 1)] - h.eval(s)).norm() < 1e-13);
        assert!((resp[(1, 0)] - g.eval(s)).norm() < 1e-13);
        assert!(resp[(1, 1)].norm() == 0.0);
        let bad = GeneralizedPlant::from_tf_blocks(&[vec![None, None]], &[], &[], &[], dims);
        assert!(matches!(bad, Err(LtiError::Dimension { .. })));
    }

    #[test]
    fn a_mode_has_the_transfer_function_of_a_damped_oscillator() {
        let (w, z) = (30.0, 0.05);
        let mode = Mode {
            omega: w,
            zeta: z,
            b_u: vec![2.0],
            b_w: vec![],
            c_y: vec![3.0],
            c_y_vel: vec![0.5],
            c_z: vec![],
            c_z_vel: vec![],
        };
        let dims = ChannelDims {
            n_u: 1,
            n_w: 0,
            n_y: 1,
            n_z: 0,
        };
        let p = GeneralizedPlant::from_modes(&[mode], dims).unwrap();
        let s = Complex::new(0.0, 25.0);
        let want = (s * 0.5 + 3.0) * 2.0 / (s * s + s * (2.0 * z * w) + w * w);
        let got = p.state_space().freq_response(s).unwrap()[(0, 0)];
        assert!((got - want).norm() < 1e-14 * want.norm());
    }
}
