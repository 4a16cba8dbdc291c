//! Geodesy and rotations: the WGS84 ellipsoid, frame rotations, map projections.
//!
//! Frames (conventions §3): `e` ECEF WGS84; `n` local North-East-Down; `b` body (x fwd, y right, z
//! down); `s` scanner. All angles in radians, lengths in metres.

pub mod ellipsoid;
pub(crate) mod epsg;
mod epsg_axes;
pub mod geoid;
mod geoid_tiff;
mod geoid_vertical;
pub mod local;
pub mod projection;
pub mod rotations;
mod utm;
