//! Several surveys of one mount as one observation set (a day's passes, docs/nightly.md): their
//! observations side by side, sharing the catalogue effects (one mounting, one clock) and the
//! references (by id), each keeping its own visits and passes.
//!
//! The navigation errors need nothing more: without correlation times every visit has its own
//! error; with them the error is a process in GPS time ([`super::continuous`]), and the
//! surveys of one day share one trajectory (the template's SBET), so returns at different
//! times get different knots (their errors correlated by `exp(-dt / tau)`, nothing across a
//! gap much longer than tau) and returns at the same time share the one navigation error of
//! that time, as the profile files of one survey do.

use super::{invalid, ObservationSet};
use crate::Result;

impl ObservationSet {
    /// `sets` as one set: references merged by id (in order of first appearance), visits and
    /// passes numbered after those of the sets before. The sets must agree on the correlation
    /// times. One set is returned as it is; the sets are moved in, each released once joined
    /// (the observations are the diagnosis' largest allocation: never held twice whole).
    pub fn join(sets: Vec<ObservationSet>) -> Result<ObservationSet> {
        let Some(first) = sets.first() else {
            return Err(invalid("no observation set to join".into()));
        };
        if let Some(k) = sets.iter().position(|s| {
            s.nav_tau_s != first.nav_tau_s
                || s.nav_white_share != first.nav_white_share
                || s.nav_slow != first.nav_slow
        }) {
            let model = |s: &ObservationSet| {
                format!(
                    "nav_tau_s = {:?}, nav_white_share = {:?}, nav_slow = {:?}",
                    s.nav_tau_s, s.nav_white_share, s.nav_slow
                )
            };
            return Err(invalid(format!(
                "set {k} has {}, set 0 {}: surveys of one mount share one navigation error model",
                model(&sets[k]),
                model(first)
            )));
        }
        if sets.len() == 1 {
            return Ok(sets.into_iter().next().expect("one set"));
        }
        let mut joint = ObservationSet {
            nav_tau_s: first.nav_tau_s,
            nav_white_share: first.nav_white_share,
            nav_slow: first.nav_slow,
            ..Default::default()
        };
        joint
            .observations
            .reserve_exact(sets.iter().map(|s| s.observations.len()).sum());
        joint
            .visits
            .reserve_exact(sets.iter().map(|s| s.visits.len()).sum());
        for set in sets {
            let reference: Vec<usize> = set
                .reference_ids
                .iter()
                .map(|id| joint.reference_index(id))
                .collect();
            let (visits, passes) = (joint.visits.len(), joint.passes);
            joint.visits.extend(set.visits.into_iter().map(|mut v| {
                v.reference = reference[v.reference];
                v.pass += passes;
                v
            }));
            joint
                .observations
                .extend(set.observations.into_iter().map(|mut o| {
                    o.reference = reference[o.reference];
                    o.visit += visits;
                    o.covariates.reference_id = o.reference;
                    o.covariates.pass += passes;
                    o
                }));
            joint.passes += set.passes;
        }
        Ok(joint)
    }

    /// The index of reference `id`, added when new.
    fn reference_index(&mut self, id: &str) -> usize {
        match self.reference_ids.iter().position(|r| r == id) {
            Some(i) => i,
            None => {
                self.reference_ids.push(id.to_string());
                self.reference_ids.len() - 1
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::synthetic::{draw, Scenario};
    use super::*;
    use crate::testing::min_of;

    /// Two passes of one mount over the same references, drawn independently: the joint fit
    /// of the effect is the inverse-variance combination of the passes' own fits on the same
    /// references (their information adds): visits independent, or Gauss-Markov navigation
    /// errors of passes far apart in time (1000 s against tau = 20 s).
    #[test]
    fn joint_fit_combines_the_passes_information() {
        for tau in [None, Some([20.0, 20.0])] {
            let effect = super::super::Effect::BoresightX;
            let sc = Scenario {
                truth: vec![(effect, 0.1)],
                nav_tau_s: tau,
                ..Scenario::default()
            };
            let a = draw(&sc, 1);
            let mut b = draw(&sc, 2);
            // b 1000 s after a, its knot grid in the same phase as on its own (the grid starts
            // at a set's first return; another phase is another discretisation).
            let first =
                |s: &ObservationSet| min_of(s.observations.iter().map(|o| o.covariates.time_s));
            let shift = 1000.0 + first(&a) - first(&b);
            for o in &mut b.observations {
                o.covariates.time_s += shift;
            }
            let joint = ObservationSet::join(vec![a.clone(), b.clone()]).unwrap();
            let fit = |s: &ObservationSet| {
                let refs: Vec<usize> = (0..s.reference_ids.len()).collect();
                let f = crate::app::diagnose::model::fit::fit(s, &refs, &[effect]).unwrap();
                (f.estimate[0], f.sigma[0])
            };
            let ((xa, sa), (xb, sb), (xj, sj)) = (fit(&a), fit(&b), fit(&joint));
            let (wa, wb) = (sa.powi(-2), sb.powi(-2));
            let combined = (wa * xa + wb * xb) / (wa + wb);
            let info = sj.powi(-2) / (wa + wb) - 1.0;
            assert!(info.abs() < 1e-9, "{tau:?}: {sj} {sa} {sb}");
            assert!(
                (xj - combined).abs() < 1e-9 * sj,
                "{tau:?}: {xj} {combined}"
            );
            assert!(sj < sa.min(sb));
        }
    }

    #[test]
    fn one_set_joins_to_itself() {
        let set = draw(&Scenario::default(), 3);
        assert_eq!(ObservationSet::join(vec![set.clone()]).unwrap(), set);
    }

    /// Two surveys: references merged by id, visits and passes of the second numbered after
    /// the first's, the joint set valid.
    #[test]
    fn two_sets_share_references_by_id() {
        let a = draw(&Scenario::default(), 1);
        let mut b = draw(&Scenario::default(), 2);
        b.reference_ids.reverse();
        let n = b.reference_ids.len();
        for o in &mut b.observations {
            o.reference = n - 1 - o.reference;
            o.covariates.reference_id = o.reference;
        }
        for v in &mut b.visits {
            v.reference = n - 1 - v.reference;
        }
        let joint = ObservationSet::join(vec![a.clone(), b.clone()]).unwrap();
        joint.validate().unwrap();
        assert_eq!(joint.reference_ids, a.reference_ids);
        assert_eq!(joint.passes, a.passes + b.passes);
        assert_eq!(joint.visits.len(), a.visits.len() + b.visits.len());
        let (o, p) = (
            &joint.observations[a.observations.len()],
            &b.observations[0],
        );
        assert_eq!(
            joint.reference_ids[o.reference],
            b.reference_ids[p.reference]
        );
        assert_eq!(o.visit, a.visits.len() + p.visit);
        assert_eq!(o.covariates.pass, a.passes + p.covariates.pass);
        assert_eq!(o.residual_m, p.residual_m);
        let mut c = b;
        c.nav_tau_s = Some([30.0, 30.0]);
        let e = ObservationSet::join(vec![a, c]).unwrap_err().to_string();
        assert!(e.contains("set 1") && e.contains("nav_tau_s"), "{e}");
    }
}
