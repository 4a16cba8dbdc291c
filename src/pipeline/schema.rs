//! The output schema, built once from the pipeline: which extra dimensions a run writes, in
//! record order, their slots in [`LasPoint::extra`] and their byte offsets in a record's extra
//! bytes; and [`PointFill`], which fills a [`LasPoint`] in place from a georeferenced return.
//!
//! Extra dimensions, in order: `range` (`output.range_dimension`), `return_index`
//! (`output.return_index_dimension`), then with `[uncertainty]` `sigma_x`, `sigma_y`,
//! `sigma_z`, with `write_95` `thu95`, `tvu95`, with `write_shares` the six `share_<group>`
//! (docs/uncertainty.md), then `mirror_angle` (`output.mirror_angle_dimension`).

use super::config::{FrameConfig, PipelineConfig, UncertaintyConfig};
use super::georeference::GeoreferencedReturn;
use crate::geo::projection::MapFrame;
use crate::geo::rotations::wrap_pi;
use crate::io::las::{ExtraDim, LasPoint};
use crate::io::profiles::RawReturn;
use crate::uncertainty::propagate::{AxisVariances, TVU95_FACTOR};
use crate::uncertainty::Group;

/// Slots (indices in [`LasPoint::extra`]) of the uncertainty dimensions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UncertaintySlots {
    /// `sigma_x`; `sigma_y` and `sigma_z` follow.
    pub sigma_x: usize,
    /// `thu95`, `tvu95` follows (with `write_95`).
    pub thu95: Option<usize>,
    /// The first `share_<group>`, the others follow in [`Group::ALL`] order (with
    /// `write_shares`).
    pub shares: Option<usize>,
}

/// The extra dimensions of a run and where each lives.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputSchema {
    dims: Vec<ExtraDim>,
    /// Slot of `range` (m).
    pub range: Option<usize>,
    /// Slot of `return_index`.
    pub return_index: Option<usize>,
    /// Slot of `mirror_angle` (deg).
    pub mirror_angle: Option<usize>,
    /// Slots of the uncertainty dimensions.
    pub uncertainty: Option<UncertaintySlots>,
    /// File units per metre of Z and the sigmas: 1 but for an EPSG CRS in feet, whose X and Y
    /// come in its unit from the projection (docs/output.md).
    pub units_per_m: f64,
}

impl OutputSchema {
    /// The schema of a pipeline.
    pub fn new(c: &PipelineConfig) -> Self {
        let mut s = OutputSchema {
            dims: Vec::new(),
            range: None,
            return_index: None,
            mirror_angle: None,
            uncertainty: None,
            units_per_m: match c.output.frame {
                FrameConfig::Epsg { code } => {
                    MapFrame::from_epsg(code).map_or(1.0, |f| 1.0 / f.metres_per_unit())
                }
                _ => 1.0,
            },
        };
        if c.output.range_dimension {
            s.range = Some(s.push(ExtraDim::f32("range", "measured range rho (m)")));
        }
        if c.output.return_index_dimension {
            let dim = ExtraDim::f64("return_index", "record index in profile file");
            s.return_index = Some(s.push(dim));
        }
        if let Some(u) = &c.uncertainty {
            s.uncertainty = Some(s.push_uncertainty(u));
        }
        if c.output.mirror_angle_dimension {
            let dim = ExtraDim::f32("mirror_angle", "recorded mirror angle (deg)");
            s.mirror_angle = Some(s.push(dim));
        }
        s
    }

    /// The uncertainty dimensions of `u` alone, in the order and with the names `run` gives
    /// them (what `kinescan tpu` appends to a cloud), in metres.
    pub fn uncertainty_only(u: &UncertaintyConfig) -> Self {
        let mut s = OutputSchema {
            dims: Vec::new(),
            range: None,
            return_index: None,
            uncertainty: None,
            mirror_angle: None,
            units_per_m: 1.0,
        };
        s.uncertainty = Some(s.push_uncertainty(u));
        s
    }

    /// Appends `dim`, giving its slot.
    fn push(&mut self, dim: ExtraDim) -> usize {
        self.dims.push(dim);
        self.dims.len() - 1
    }

    fn push_uncertainty(&mut self, u: &UncertaintyConfig) -> UncertaintySlots {
        // Descriptions (32 bytes at most) name the unit: metres, or the feet of a foot CRS.
        let unit = if self.units_per_m == 1.0 { "m" } else { "ft" };
        let dim = |name: &str, what: &str| ExtraDim::f32(name, &format!("{what} ({unit})"));
        let sigma_x = self.push(dim("sigma_x", "1-sigma along X"));
        self.push(dim("sigma_y", "1-sigma along Y"));
        self.push(dim("sigma_z", "1-sigma along Z"));
        let thu95 = u.write_95.then(|| {
            // 32 bytes with "(m)"; one fewer comma to fit "(ft)".
            let what = if unit == "m" {
                "95% horizontal, 1.7308 sig_r"
            } else {
                "95% horizontal 1.7308 sig_r"
            };
            let first = self.push(dim("thu95", what));
            self.push(dim("tvu95", "95% vertical, 1.96 sigma_z"));
            first
        });
        let shares = u.write_shares.then(|| {
            let first = self.dims.len();
            for g in Group::ALL {
                let name = format!("share_{}", g.name());
                let desc = format!("{} variance share", g.name());
                self.push(ExtraDim::fraction(&name, &desc));
            }
            first
        });
        UncertaintySlots {
            sigma_x,
            thu95,
            shares,
        }
    }

    /// The extra dimensions, in record order.
    pub fn dims(&self) -> &[ExtraDim] {
        &self.dims
    }

    /// Byte offset of the dimension in `slot` within a record's extra bytes (after the 30
    /// bytes of point format 6).
    pub fn extra_byte_offset(&self, slot: usize) -> usize {
        self.dims[..slot].iter().map(|d| d.data_type.size()).sum()
    }

    /// The per-point fill for points of `point_source_id`.
    pub fn fill(&self, point_source_id: u16) -> PointFill {
        PointFill {
            point_source_id,
            range: self.range,
            return_index: self.return_index,
            mirror_angle: self.mirror_angle,
            uncertainty: self.uncertainty,
            units_per_m: self.units_per_m,
        }
    }
}

/// Fills a [`LasPoint`] in place (a point is ~190 bytes: moving it per return costs more than
/// the georeferencing arithmetic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointFill {
    point_source_id: u16,
    range: Option<usize>,
    return_index: Option<usize>,
    mirror_angle: Option<usize>,
    uncertainty: Option<UncertaintySlots>,
    units_per_m: f64,
}

impl PointFill {
    /// The point of raw return `r` (record `index` of its file) georeferenced as `g`: map
    /// coordinates, intensity, scan angle (LAS 1.4: from nadir, positive to the right looking
    /// forward), GPS time, point source, `range`, `return_index`, `mirror_angle`.
    #[inline]
    pub fn point(&self, r: &RawReturn, index: usize, g: &GeoreferencedReturn, p: &mut LasPoint) {
        // x, y come in the CRS's unit from the projection; z (m) is converted to it (an exact
        // multiplication by 1 for a metric frame).
        (p.x, p.y, p.z) = (g.x_map_m.x, g.x_map_m.y, g.x_map_m.z * self.units_per_m);
        p.intensity = r.intensity;
        p.scan_angle_deg = g.scan_angle_rad.to_degrees();
        p.gps_time = g.t_s;
        p.point_source_id = self.point_source_id;
        if let Some(k) = self.range {
            p.extra[k] = r.range_m;
        }
        if let Some(k) = self.return_index {
            p.extra[k] = index as f64;
        }
        if let Some(k) = self.mirror_angle {
            p.extra[k] = wrap_pi(r.beta_rad).to_degrees();
        }
    }

    /// The uncertainty dimensions of `var`.
    #[inline]
    pub fn uncertainty(&self, var: &AxisVariances, p: &mut LasPoint) {
        let Some(u) = self.uncertainty else { return };
        // In the file's unit (m, or the feet of a foot CRS).
        let sigma = var.sigma_xyz_m() * self.units_per_m;
        p.extra[u.sigma_x..u.sigma_x + 3].copy_from_slice(sigma.as_slice());
        if let Some(k) = u.thu95 {
            // tvu95 = var.tvu95_m() without a second sqrt.
            let thu95 = var.thu95_m() * self.units_per_m;
            p.extra[k..k + 2].copy_from_slice(&[thu95, TVU95_FACTOR * sigma.z]);
        }
        if let Some(k) = u.shares {
            let shares = var.shares();
            p.extra[k..k + shares.len()].copy_from_slice(&shares);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_follow_the_dimension_sizes() {
        let text = r#"
            [inputs]
            sbet = "a.sbet"
            smrmsg = "a.smrmsg"
            profiles = ["p.ksprof"]
            [sensor]
            lever_arm_b_m = [0.0, 0.0, 0.0]
            [time]
            t0_s = 0.0
            period_s = 0.01
            [output]
            las = "out.las"
            return_index_dimension = true
            [uncertainty]
            sigma_lever_arm_b_m = [0.0, 0.0, 0.0]
            sigma_boresight_deg = [0.0, 0.0, 0.0]
            sigma_alpha_deg = 0.0
            sigma_beta_deg = 0.0
            sigma_range_m = 0.0
            sigma_range_zero_m = 0.0
            clock_covariance_s2 = [[0.0, 0.0], [0.0, 0.0]]
            sigma_attitude_latency_s = 0.0
            write_shares = true
        "#;
        let c: PipelineConfig = toml::from_str(text).unwrap();
        let s = OutputSchema::new(&c);
        let u = s.uncertainty.unwrap();
        assert_eq!((s.range, s.return_index), (Some(0), Some(1)));
        assert_eq!((u.sigma_x, u.thu95, u.shares), (2, None, Some(5)));
        assert_eq!(s.dims().len(), 12);
        // range f32, return_index f64, three f32 sigmas, six share bytes, mirror_angle last.
        assert_eq!(s.extra_byte_offset(1), 4);
        assert_eq!(s.extra_byte_offset(u.sigma_x), 12);
        assert_eq!(s.extra_byte_offset(5), 24);
        assert_eq!(s.mirror_angle, Some(11));
        assert_eq!(s.extra_byte_offset(11), 30);
        assert_eq!(s.units_per_m, 1.0);
    }
}
