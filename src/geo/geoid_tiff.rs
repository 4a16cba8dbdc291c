//! GeoTIFF geoid grids as PROJ ships them (PROJ's "GeoTIFF grid" format): the first image of
//! the file, one Float32 sample per pixel (any compression and predictor the `tiff` crate
//! decodes: none, DEFLATE, LZW; floating-point predictor), georeferenced by `ModelTiepoint` and
//! `ModelPixelScale` in degrees, `GTRasterTypeGeoKey` = PixelIsArea (default: the tie point is
//! a pixel corner, nodes at pixel centres) or PixelIsPoint, no-data from `GDAL_NODATA`.

use std::io::Cursor;
use std::path::Path;

use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

use crate::{Error, Result};

/// GeoTIFF key of the raster type (1 = PixelIsArea, 2 = PixelIsPoint).
const GT_RASTER_TYPE_GEO_KEY: u16 = 1025;
const RASTER_PIXEL_IS_POINT: u16 = 2;
/// GDAL's no-data tag (ASCII).
const GDAL_NODATA_TAG: u16 = 42113;

/// A grid as the file stores it: south-west node and steps `[south, west, dlat, dlon]` (deg),
/// rows and columns, values row-major from the south row (NaN for no data).
pub(crate) struct RawGrid {
    pub corner_step_deg: [f64; 4],
    pub rows: usize,
    pub cols: usize,
    pub n_m: Vec<f32>,
}

/// Reads the grid in `bytes` (the content of `path`).
pub(crate) fn read(path: &Path, bytes: &[u8]) -> Result<RawGrid> {
    let bad = |problem: String| Error::bad_file(path, problem);
    let tiff_err = |e: tiff::TiffError| bad(format!("not a readable GeoTIFF grid: {e}"));
    let mut dec = Decoder::new(Cursor::new(bytes)).map_err(tiff_err)?;
    let (cols, rows) = dec.dimensions().map_err(tiff_err)?;
    let (cols, rows) = (cols as usize, rows as usize);
    let scale = dec
        .get_tag_f64_vec(Tag::ModelPixelScaleTag)
        .map_err(|e| bad(format!("no ModelPixelScale tag: {e}")))?;
    let tie = dec
        .get_tag_f64_vec(Tag::ModelTiepointTag)
        .map_err(|e| bad(format!("no ModelTiepoint tag: {e}")))?;
    if scale.len() < 2 || tie.len() < 6 {
        return Err(bad("ModelPixelScale or ModelTiepoint too short".into()));
    }
    let pixel_is_point = dec
        .find_tag(Tag::GeoKeyDirectoryTag)
        .ok()
        .flatten()
        .and_then(|v| v.into_u16_vec().ok())
        .is_some_and(|keys| raster_type(&keys) == Some(RASTER_PIXEL_IS_POINT));
    let no_data = dec
        .find_tag(Tag::Unknown(GDAL_NODATA_TAG))
        .ok()
        .flatten()
        .and_then(|v| v.into_string().ok())
        .and_then(|s| s.trim_matches(char::from(0)).trim().parse::<f32>().ok());
    let values = match dec.read_image().map_err(tiff_err)? {
        DecodingResult::F32(v) if v.len() == rows * cols => v,
        DecodingResult::F32(v) => {
            return Err(bad(format!(
                "{} samples for {rows} x {cols} pixels: only one band is supported",
                v.len()
            )))
        }
        _ => return Err(bad("samples are not Float32".into())),
    };
    // Rows run north to south; the grid wants them south to north.
    let n_m = values
        .chunks_exact(cols)
        .rev()
        .flatten()
        .map(|&v| if Some(v) == no_data { f32::NAN } else { v })
        .collect();
    let half = if pixel_is_point { 0.0 } else { 0.5 };
    let (dlon, dlat) = (scale[0], scale[1]);
    let west = tie[3] + (half - tie[0]) * dlon;
    let north = tie[4] - (half - tie[1]) * dlat;
    let south = north - dlat * (rows as f64 - 1.0);
    Ok(RawGrid {
        corner_step_deg: [south, west, dlat, dlon],
        rows,
        cols,
        n_m,
    })
}

/// The value of `GTRasterTypeGeoKey` in a GeoKeyDirectory (header of 4 shorts, then entries
/// of 4: key, location, count, value).
fn raster_type(keys: &[u16]) -> Option<u16> {
    keys.get(4..)?
        .chunks_exact(4)
        .find(|k| k[0] == GT_RASTER_TYPE_GEO_KEY && k[1] == 0)
        .map(|k| k[3])
}
