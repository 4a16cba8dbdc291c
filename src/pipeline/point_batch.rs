//! [`PointBatch`]: a worker's points between georeferencing and encoding. Points are filled
//! in place; with `[uncertainty]` their propagation inputs are gathered beside them and
//! propagated together ([`VarianceBatch`], vectorised) just before the batch is encoded.

use super::georeference::{GeoreferencedReturn, ReturnCursors, ReturnGeoreferencer};
use super::schema::PointFill;
use super::write::encode_error;
use crate::io::las::{encode_points, ChunkStats, LasPoint, PointLayout};
use crate::io::profiles::{ProfileFile, RawReturn};
use crate::uncertainty::batch::{VarianceBatch, BATCH_RETURNS};
use crate::Result;

/// Up to [`BATCH_RETURNS`] points (a size that keeps them in cache), the records they come
/// from and, with `[uncertainty]`, their propagation inputs.
pub(super) struct PointBatch {
    points: Vec<LasPoint>,
    records: Vec<usize>,
    variances: Option<VarianceBatch>,
}

impl PointBatch {
    /// An empty batch for the returns of `geo`.
    pub(super) fn new(geo: &ReturnGeoreferencer) -> Self {
        PointBatch {
            points: vec![LasPoint::default(); BATCH_RETURNS],
            records: Vec::with_capacity(BATCH_RETURNS),
            variances: geo.propagator().map(|_| VarianceBatch::default()),
        }
    }

    /// Whether the batch is full (to be [flushed](Self::flush)).
    pub(super) fn is_full(&self) -> bool {
        self.records.len() == BATCH_RETURNS
    }

    /// Adds raw return `r` (record `index` of its file) georeferenced as `g`.
    #[inline]
    pub(super) fn push(
        &mut self,
        (r, index, g): (&RawReturn, usize, &GeoreferencedReturn),
        fill: &PointFill,
        geo: &ReturnGeoreferencer,
        cursors: &mut ReturnCursors,
    ) {
        let k = self.records.len();
        fill.point(r, index, g, &mut self.points[k]);
        if let Some(v) = self.variances.as_mut() {
            if let Some(x) = geo.variance_inputs(g, cursors) {
                v.push(&x);
            }
        }
        self.records.push(index);
    }

    /// Propagates the batch's uncertainty, encodes its points (appending the records to
    /// `out` and giving their stats) and empties it. A point that cannot be encoded is named
    /// by its record of `file`, and a coordinate beyond the LAS range by the keys that fix it.
    pub(super) fn flush(
        &mut self,
        fill: &PointFill,
        geo: &ReturnGeoreferencer,
        layout: &PointLayout,
        file: &ProfileFile,
        out: &mut Vec<u8>,
    ) -> Result<ChunkStats> {
        let n = self.records.len();
        let points = &mut self.points[..n];
        if let (Some(v), Some(p)) = (self.variances.as_mut(), geo.propagator()) {
            if v.len() == n {
                v.propagate(p);
                for (k, point) in points.iter_mut().enumerate() {
                    fill.uncertainty(&v.variances(k), point);
                }
            }
            v.clear();
        }
        let stats = encode_points(points, layout, out)
            .map_err(|e| encode_error(e, points, &self.records, layout, file));
        self.records.clear();
        stats
    }
}
