//! [`VarianceBatch`]: the propagation of many returns at once, bit for bit that of
//! [`Propagator::variances`] one return at a time.
//!
//! The returns' [`ReturnInputs`] are stored by column (one array per value), so the loop over
//! returns is one straight-line body on unit-stride arrays that the compiler vectorises: each
//! lane does the very IEEE operations of the scalar code in the same order (no reassociation,
//! no fused multiply-add), so the variances are identical. A vector holds eight returns with
//! AVX-512, four with AVX2 (detected at run time), else two.

use super::propagate::{AxisVariances, Propagator, ReturnInputs};
use super::N_GROUPS;
use nalgebra::Vector3;

/// Returns per batch.
pub const BATCH_RETURNS: usize = 256;

/// Length of a column: one cache line more than the batch, so that a return's values in
/// successive columns fall in different cache sets (at a power-of-two stride they would all
/// compete for the same two sets of L1 and evict each other).
const COLUMN_LEN: usize = BATCH_RETURNS + 8;

/// The inputs of up to [`BATCH_RETURNS`] returns by column, and their variances once
/// [`VarianceBatch::propagate`] has run.
pub struct VarianceBatch {
    len: usize,
    inputs: Box<[[f64; COLUMN_LEN]; ReturnInputs::LEN]>,
    /// Variance along X, Y, Z (m^2), then the group variances.
    outputs: Box<[[f64; COLUMN_LEN]; 3 + N_GROUPS]>,
}

impl Default for VarianceBatch {
    fn default() -> Self {
        VarianceBatch {
            len: 0,
            inputs: columns(),
            outputs: columns(),
        }
    }
}

/// `N` zeroed columns, allocated on the heap directly.
fn columns<const N: usize>() -> Box<[[f64; COLUMN_LEN]; N]> {
    let columns = vec![[0.0; COLUMN_LEN]; N].into_boxed_slice();
    columns.try_into().expect("N columns")
}

impl VarianceBatch {
    /// Returns held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no return is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Empties the batch.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Adds one return's inputs (at most [`BATCH_RETURNS`] between clears).
    #[inline]
    pub fn push(&mut self, x: &ReturnInputs) {
        assert!(self.len < BATCH_RETURNS, "variance batch full");
        for (column, v) in self.inputs.iter_mut().zip(x.values()) {
            column[self.len] = v;
        }
        self.len += 1;
    }

    /// Propagates every return held; [`Self::variances`] gives the results.
    pub fn propagate(&mut self, p: &Propagator) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F.
            return unsafe { self.propagate_avx512(p) };
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2.
            return unsafe { self.propagate_avx2(p) };
        }
        self.propagate_lanes(p)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn propagate_avx512(&mut self, p: &Propagator) {
        self.propagate_lanes(p)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn propagate_avx2(&mut self, p: &Propagator) {
        self.propagate_lanes(p)
    }

    #[inline(always)]
    fn propagate_lanes(&mut self, p: &Propagator) {
        if p.with_groups() {
            self.propagate_with::<true>(p)
        } else {
            self.propagate_with::<false>(p)
        }
    }

    #[inline(always)]
    fn propagate_with<const GROUPS: bool>(&mut self, p: &Propagator) {
        let (inputs, outputs) = (&*self.inputs, &mut *self.outputs);
        for lane in 0..self.len.min(BATCH_RETURNS) {
            let values = std::array::from_fn(|k| inputs[k][lane]);
            let v = p.variances_of::<GROUPS>(&ReturnInputs::from_values(&values));
            let results = v.var_m2.iter().chain(&v.group_variance_m2);
            for (column, r) in outputs.iter_mut().zip(results) {
                column[lane] = *r;
            }
        }
    }

    /// The variances of the `k`-th return pushed (after [`Self::propagate`]).
    #[inline]
    pub fn variances(&self, k: usize) -> AxisVariances {
        let o = &self.outputs;
        AxisVariances {
            var_m2: Vector3::new(o[0][k], o[1][k], o[2][k]),
            group_variance_m2: std::array::from_fn(|g| o[3 + g][k]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::rotations::r_zyx;
    use crate::georef::{ReturnTerms, Sensor};
    use crate::trajectory::NavSigma;
    use crate::uncertainty::propagate::UncertaintyInputs;
    use nalgebra::{Matrix2, Matrix3};

    /// A batch gives the bits of one return at a time, with and without groups, for varied
    /// geometries and sigmas (a zero, a tiny and a huge one among them).
    #[test]
    fn batch_equals_one_return_at_a_time_bit_for_bit() {
        let sensor = Sensor::new(
            Vector3::new(0.4, -0.3, -1.6),
            Vector3::new(0.03, -0.04, 1.6),
            0.002,
            0.01,
        );
        let inputs = UncertaintyInputs {
            sigma_lever_arm_b_m: Vector3::new(0.01, 0.0, 0.02),
            sigma_boresight_rad: Vector3::new(1e-4, 2e-4, 3e-4),
            sigma_alpha_rad: 1e-4,
            sigma_beta_rad: 2e-4,
            sigma_range_m: 0.005,
            sigma_range_zero_m: 0.003,
            clock_covariance_s2: Matrix2::new(1e-8, 1e-12, 1e-12, 1e-16),
            sigma_attitude_latency_s: 2e-4,
        };
        let n = BATCH_RETURNS - 3;
        let cases: Vec<ReturnInputs> = (0..n)
            .map(|k| {
                let f = k as f64;
                let r_b_n = r_zyx(0.01 * f.sin(), -0.02 * f.cos(), 0.1 * f);
                let r_n_e = r_zyx(0.3, 0.8 + 1e-3 * f, -0.2);
                let terms = ReturnTerms::new(
                    r_n_e,
                    r_b_n,
                    &sensor.lever_arm_b_m,
                    &sensor.r_s_to_b,
                    0.002,
                    0.05 * f,
                    3.0 + 0.37 * f,
                );
                let mut dtheta = Matrix3::zeros();
                (dtheta[(0, 1)], dtheta[(1, 0)], dtheta[(2, 1)]) = (1.6e-7, -1.6e-7, 1.8e-7);
                let nav = NavSigma {
                    pos_ned_m: Vector3::new(0.02, [0.0, 1e-300, 1e150][k % 3], 0.03),
                    att_rph_rad: Vector3::new(1e-4, 2e-4, 5e-4 * f),
                };
                ReturnInputs::new(
                    &(r_zyx(0.0, 0.0, 0.02) * 0.9996 * r_n_e.transpose() * r_n_e),
                    &dtheta,
                    &terms,
                    &Vector3::new(0.1, -0.2, 0.05 * f),
                    &Vector3::new(15.0, 0.1 * f, -0.2),
                    &nav,
                    [1.0, 1e4 + f],
                )
            })
            .collect();
        // A path this CPU cannot run is a skip, a failure where CI forces it
        // (`KINESCAN_REQUIRE_AVX2=1` / `KINESCAN_REQUIRE_AVX512=1`: `.ci/run` sets them from
        // /proc/cpuinfo).
        #[cfg(target_arch = "x86_64")]
        let (avx2, avx512) = (
            std::arch::is_x86_feature_detected!("avx2"),
            std::arch::is_x86_feature_detected!("avx512f"),
        );
        #[cfg(not(target_arch = "x86_64"))]
        let (avx2, avx512) = (false, false);
        let test = "batch_equals_one_return_at_a_time_bit_for_bit";
        if !avx2 {
            crate::testing::skip("KINESCAN_REQUIRE_AVX2", test, "no AVX2 on this CPU");
        }
        if !avx512 {
            crate::testing::skip("KINESCAN_REQUIRE_AVX512", test, "no AVX-512F on this CPU");
        }
        for groups in [false, true] {
            let p = Propagator::new(inputs, groups, sensor.lever_arm_b_m, sensor.r_s_to_b);
            // Every path this CPU can run: dispatched, baseline, AVX2, AVX-512.
            let mut batches = Vec::new();
            let mut run = |f: &dyn Fn(&mut VarianceBatch)| {
                let mut batch = VarianceBatch::default();
                cases.iter().for_each(|x| batch.push(x));
                f(&mut batch);
                batches.push(batch);
            };
            run(&|b| b.propagate(&p));
            run(&|b| b.propagate_lanes(&p));
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: the CPU has AVX2.
                run(&|b| unsafe { b.propagate_avx2(&p) });
            }
            #[cfg(target_arch = "x86_64")]
            if avx512 {
                // SAFETY: the CPU has AVX-512F.
                run(&|b| unsafe { b.propagate_avx512(&p) });
            }
            for (k, x) in cases.iter().enumerate() {
                let one = if groups {
                    p.variances_of::<true>(x)
                } else {
                    p.variances_of::<false>(x)
                };
                let bits = |v: &AxisVariances| {
                    let all = v.var_m2.iter().chain(&v.group_variance_m2);
                    all.map(|x| x.to_bits()).collect::<Vec<_>>()
                };
                for (path, batch) in batches.iter().enumerate() {
                    let got = batch.variances(k);
                    assert_eq!(
                        bits(&got),
                        bits(&one),
                        "return {k}, groups {groups}, path {path}"
                    );
                }
            }
        }
    }
}
