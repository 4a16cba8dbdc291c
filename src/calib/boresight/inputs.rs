//! The lab's CSV files: ellipse centres, site attitudes, or raw static scans (centres fitted).

use super::estimate::TripodSite;
use crate::calib::ellipse::{fit_site_centres, LegScanModel, ScanReturn};
use crate::calib::tripod::BoresightSetup;
use crate::geo::rotations::r_b_to_n;
use crate::io::csv_text::CsvTable;
use crate::{Error, Result};
use nalgebra::{Matrix2, Vector2};
use std::collections::BTreeMap;
use std::path::Path;

/// Centre and sigma (m) of legs 1, 2, 3 at one site, as read.
type SiteLegs = [Option<(Vector2<f64>, f64)>; 3];

/// Reads the ellipse centres and site attitudes into sites (sorted by id). Each site must have
/// exactly legs 1, 2 and 3 (a cut that misses a leg is an error naming the site).
pub fn read_sites(centres: &Path, attitudes: &Path) -> Result<Vec<TripodSite>> {
    let t = CsvTable::read(centres)?;
    let (cs, cl, cy, cz, csig) = (
        t.column("site")?,
        t.column("leg")?,
        t.column("y_s_m")?,
        t.column("z_s_m")?,
        t.column("sigma_m")?,
    );
    let mut legs: BTreeMap<u64, SiteLegs> = BTreeMap::new();
    for (line, f) in t.rows() {
        let site = t.u64(line, f, cs)?;
        let leg = t.u64(line, f, cl)?;
        if !(1..=3).contains(&leg) {
            return Err(t.bad(line, format!("leg {leg}: legs are numbered 1, 2, 3")));
        }
        let sigma = t.f64(line, f, csig)?;
        if !crate::calib::positive(sigma) {
            return Err(t.bad(line, "sigma_m must be > 0"));
        }
        let slot = &mut legs.entry(site).or_default()[leg as usize - 1];
        if slot.is_some() {
            return Err(t.bad(line, format!("site {site}: leg {leg} given twice")));
        }
        *slot = Some((
            Vector2::new(t.f64(line, f, cy)?, t.f64(line, f, cz)?),
            sigma,
        ));
    }
    with_attitudes(legs, attitudes, "ellipse centres", |site, l, att, sig| {
        let found: Vec<usize> = (0..3).filter(|&i| l[i].is_some()).map(|i| i + 1).collect();
        if found.len() != 3 {
            return Err(Error::bad_file(
                centres,
                format!(
                    "site {site}: the scan plane must cut all three legs, found legs {found:?}"
                ),
            ));
        }
        let l = l.map(|x| x.unwrap_or_default());
        Ok(TripodSite {
            site,
            centres_s_m: l.map(|x| x.0),
            cov_centre_s_m2: l.map(|x| Matrix2::identity() * x.1 * x.1),
            attitude_rad: att,
            sigma_attitude_rad: sig,
        })
    })
}

/// Pairs each site's data (`by_site`, the `what` of the site, e.g. "ellipse centres") with its
/// row of `attitudes` through `site_of`, in site order; a site missing from either file is an
/// error naming it.
fn with_attitudes<T>(
    mut by_site: BTreeMap<u64, T>,
    attitudes: &Path,
    what: &str,
    mut site_of: impl FnMut(u64, T, [f64; 3], [f64; 3]) -> Result<TripodSite>,
) -> Result<Vec<TripodSite>> {
    let mut rows = read_attitudes(attitudes)?;
    rows.sort_by_key(|r| r.0);
    let mut out = Vec::new();
    for (site, line, att, sig) in rows {
        let data = by_site.remove(&site).ok_or_else(|| {
            let problem = format!("site {site} has no {what}");
            Error::bad_record(attitudes, format!("line {line}"), problem)
        })?;
        out.push(site_of(site, data, att, sig)?);
    }
    if let Some(site) = by_site.keys().next() {
        let problem = format!("site {site} has {what} but no attitude");
        return Err(Error::bad_file(attitudes, problem));
    }
    Ok(out)
}

/// One attitude row: site, line, angles and sigmas (rad).
type AttitudeRow = (u64, usize, [f64; 3], [f64; 3]);

/// Reads the site attitudes `site,roll_deg,...,sigma_heading_deg` (convention angles) in file order.
fn read_attitudes(attitudes: &Path) -> Result<Vec<AttitudeRow>> {
    let a = CsvTable::read(attitudes)?;
    let names = [
        "roll_deg",
        "pitch_deg",
        "heading_deg",
        "sigma_roll_deg",
        "sigma_pitch_deg",
        "sigma_heading_deg",
    ];
    let mut cols = [0; 6];
    for (c, n) in cols.iter_mut().zip(names) {
        *c = a.column(n)?;
    }
    let site_col = a.column("site")?;
    let mut out = Vec::new();
    for (line, f) in a.rows() {
        let site = a.u64(line, f, site_col)?;
        let mut v = [0.0; 6];
        for (k, &c) in cols.iter().enumerate() {
            v[k] = a.f64(line, f, c)?.to_radians();
        }
        out.push((site, line, [v[0], v[1], v[2]], [v[3], v[4], v[5]]));
    }
    Ok(out)
}

/// Reads raw static scans `site,beta_rad,range_m,intensity` and the site attitudes, and fits
/// each site's ellipse centres with their fitted covariances ([`fit_site_centres`]; sites in
/// id order, the legs labelled consistently with the first site's).
pub fn read_scan_sites(
    scans: &Path,
    attitudes: &Path,
    model: &LegScanModel,
    setup: &BoresightSetup,
) -> Result<Vec<TripodSite>> {
    let t = CsvTable::read(scans)?;
    let (cs, cb, cr) = (
        t.column("site")?,
        t.column("beta_rad")?,
        t.column("range_m")?,
    );
    let mut returns: BTreeMap<u64, Vec<ScanReturn>> = BTreeMap::new();
    for (line, f) in t.rows() {
        let site = t.u64(line, f, cs)?;
        let beta_rad = t.f64(line, f, cb)?;
        let range_m = t.opt_f64(line, f, cr)?.unwrap_or(0.0);
        returns
            .entry(site)
            .or_default()
            .push(ScanReturn { beta_rad, range_m });
    }
    let mut reference = None;
    with_attitudes(returns, attitudes, "scan returns", |site, r, att, sig| {
        let r_b_n = r_b_to_n(att[0], att[1], att[2]);
        let fitted = fit_site_centres(site, &r, model, setup, &r_b_n, reference.as_ref())
            .map_err(|e| Error::bad_file(scans, e.to_string()))?;
        reference.get_or_insert(fitted.legs_n_prior);
        let fits = fitted.fits;
        Ok(TripodSite {
            site,
            centres_s_m: [0, 1, 2].map(|i| fits[i].centre_s_m),
            cov_centre_s_m2: [0, 1, 2].map(|i| fits[i].cov_s_m2),
            attitude_rad: att,
            sigma_attitude_rad: sig,
        })
    })
}
