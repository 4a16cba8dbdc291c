//! Optech CSD raw airborne lidar files (docs/formats.md): a 2048-byte little-endian header,
//! then fixed 69-byte pulse records, each with its GPS time, up to four ranges and
//! intensities, the mirror's scan angle and the trajectory (roll, pitch, heading, latitude,
//! longitude, elevation) at the pulse.
//!
//! Header (packed, little-endian): signature `"CSD\0"` (4), vendor (64), software (32), f32
//! format version, u16 header size, u16 GPS week, f64 min time, f64 max time, u32 number of
//! records, u16 number of strips, 256 u32 strip pointers, 3 f64 misalignment angles (rad), 3
//! f64 IMU offsets (rad), f64 temperature, f64 pressure, free space up to the header size.
//!
//! Pulse: f64 GPS time (s of the week), u8 return count, 4 f32 ranges (m), 4 u16 intensities,
//! f32 scan angle, roll, pitch, heading (rad), f64 latitude, longitude (rad), f32 elevation (m).
//! Longitudes beyond +-2 pi (Optech's files store them below -2 pi) are brought back by one
//! turn, as PDAL's reader does.
//!
//! This module reads the values as recorded; the vendor's frame conventions (its rotation
//! order and beam) and their relation to kinescan's are in docs/tpu.md ("Real raw data").

use super::mapped::{f64_le, MappedRecords};
use crate::{Error, Result};
use std::f64::consts::TAU;
use std::io::Read;
use std::path::Path;

/// Bytes of the fixed part of the header (a header may declare more, never less).
pub const CSD_HEADER_BYTES: usize = 2048;
/// Bytes per pulse record.
pub const CSD_PULSE_BYTES: usize = 69;
/// Largest number of returns a pulse record holds.
pub const CSD_MAX_RETURNS: usize = 4;

const KIND: &str = "Optech CSD";

/// The CSD file header.
#[derive(Debug, Clone, PartialEq)]
pub struct CsdHeader {
    /// Vendor identifier (NUL-terminated text), e.g. "Optech Incorporated".
    pub vendor: String,
    /// Software that wrote the file.
    pub software: String,
    /// Format version.
    pub format_version: f32,
    /// Header size in bytes (offset of the first pulse).
    pub header_bytes: u16,
    /// GPS week of the pulse times.
    pub gps_week: u16,
    /// First and last pulse time (s of the week).
    pub time_span_s: (f64, f64),
    /// Number of pulse records.
    pub num_records: u32,
    /// Number of flight-line strips.
    pub num_strips: u16,
    /// Boresight misalignment angles (rad), in the vendor's roll, pitch, heading order.
    pub misalignment_rad: [f64; 3],
    /// IMU offset angles (rad), same order; the vendor's boresight is their sum with
    /// `misalignment_rad`.
    pub imu_offsets_rad: [f64; 3],
    /// Temperature (deg C).
    pub temperature_c: f64,
    /// Pressure (mbar).
    pub pressure_mbar: f64,
}

impl CsdHeader {
    /// The vendor's boresight angles: misalignment plus IMU offsets (rad), roll, pitch, heading.
    pub fn boresight_rad(&self) -> [f64; 3] {
        std::array::from_fn(|k| self.misalignment_rad[k] + self.imu_offsets_rad[k])
    }
}

/// One pulse record, in file units (angles in rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CsdPulse {
    /// GPS time (s of the week).
    pub time_s: f64,
    /// Number of returns recorded (ranges beyond the fourth are not stored).
    pub return_count: u8,
    /// Ranges of returns 1 to 4 (m).
    pub range_m: [f32; 4],
    /// Intensities of returns 1 to 4.
    pub intensity: [u16; 4],
    /// Mirror scan angle (rad), vendor sign.
    pub scan_angle_rad: f32,
    /// Roll (rad), vendor convention.
    pub roll_rad: f32,
    /// Pitch (rad), vendor convention.
    pub pitch_rad: f32,
    /// Heading (rad), clockwise from north.
    pub heading_rad: f32,
    /// Geodetic latitude, WGS84 (rad).
    pub lat_rad: f64,
    /// Longitude (rad), brought within +-2 pi.
    pub lon_rad: f64,
    /// Ellipsoidal height of the sensor (m).
    pub elevation_m: f32,
}

impl CsdPulse {
    /// The ranges of the returns this record holds: `min(return_count, 4)` of them (m).
    pub fn ranges_m(&self) -> &[f32] {
        &self.range_m[..(self.return_count as usize).min(CSD_MAX_RETURNS)]
    }
}

/// An open CSD file: the header and the memory-mapped pulses.
#[derive(Debug)]
pub struct CsdFile {
    header: CsdHeader,
    records: MappedRecords,
}

fn text(bytes: &[u8]) -> String {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

fn u16_le(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_le(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

fn f32_le(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

/// Parses the fixed 2048 header bytes of `path`.
fn parse_header(path: &Path, b: &[u8]) -> Result<CsdHeader> {
    if &b[..4] != b"CSD\0" {
        return Err(Error::bad_file(
            path,
            format!(
                "signature {:?} is not \"CSD\": not an Optech CSD file",
                text(&b[..4])
            ),
        ));
    }
    let header = CsdHeader {
        vendor: text(&b[4..68]),
        software: text(&b[68..100]),
        format_version: f32_le(b, 100),
        header_bytes: u16_le(b, 104),
        gps_week: u16_le(b, 106),
        time_span_s: (f64_le(b, 108), f64_le(b, 116)),
        num_records: u32_le(b, 124),
        num_strips: u16_le(b, 128),
        misalignment_rad: std::array::from_fn(|k| f64_le(b, 1154 + 8 * k)),
        imu_offsets_rad: std::array::from_fn(|k| f64_le(b, 1178 + 8 * k)),
        temperature_c: f64_le(b, 1202),
        pressure_mbar: f64_le(b, 1210),
    };
    if (header.header_bytes as usize) < CSD_HEADER_BYTES {
        return Err(Error::bad_file(
            path,
            format!(
                "header size {} B is below the format's {CSD_HEADER_BYTES} B: corrupt header",
                header.header_bytes
            ),
        ));
    }
    let mut angles = header
        .misalignment_rad
        .iter()
        .chain(&header.imu_offsets_rad);
    if let Some(bad) = angles.find(|a| a.is_nan() || a.abs() > TAU) {
        return Err(Error::bad_file(
            path,
            format!("boresight angle {bad} rad in the header is not an angle: corrupt header"),
        ));
    }
    Ok(header)
}

impl CsdFile {
    /// Opens `path`: reads and checks the header, maps the pulses, and refuses a file whose
    /// size disagrees with the header's record count (truncated or padded).
    pub fn open(path: &Path) -> Result<Self> {
        let mut head = vec![0u8; CSD_HEADER_BYTES];
        let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut got = 0;
        while got < head.len() {
            match file.read(&mut head[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(Error::io(path, e)),
            }
        }
        if got < CSD_HEADER_BYTES {
            return Err(Error::bad_file(
                path,
                format!(
                    "{KIND}: {got} bytes is shorter than the {CSD_HEADER_BYTES}-byte header \
                     (truncated or not a CSD file)"
                ),
            ));
        }
        let header = parse_header(path, &head)?;
        let records =
            MappedRecords::open(path, header.header_bytes as usize, CSD_PULSE_BYTES, KIND)?;
        if records.len() != header.num_records as usize {
            return Err(Error::bad_file(
                path,
                format!(
                    "the header announces {} pulse records, the file holds {} \
                     (truncated, or the header is corrupt)",
                    header.num_records,
                    records.len()
                ),
            ));
        }
        Ok(CsdFile { header, records })
    }

    /// The header.
    pub fn header(&self) -> &CsdHeader {
        &self.header
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        self.records.path()
    }

    /// Number of pulse records.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// True when the file holds no pulse.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Pulse `i` (0-based; panics beyond [`Self::len`]), or an error naming the file and the
    /// record when a value is not finite or the longitude is beyond +-4 pi.
    pub fn pulse(&self, i: usize) -> Result<CsdPulse> {
        let b = self.records.record(i);
        let mut p = CsdPulse {
            time_s: f64_le(b, 0),
            return_count: b[8],
            range_m: std::array::from_fn(|k| f32_le(b, 9 + 4 * k)),
            intensity: std::array::from_fn(|k| u16_le(b, 25 + 2 * k)),
            scan_angle_rad: f32_le(b, 33),
            roll_rad: f32_le(b, 37),
            pitch_rad: f32_le(b, 41),
            heading_rad: f32_le(b, 45),
            lat_rad: f64_le(b, 49),
            lon_rad: f64_le(b, 57),
            elevation_m: f32_le(b, 65),
        };
        let bad = |problem: String| Error::bad_record(self.path(), format!("pulse {i}"), problem);
        let finite = [
            ("time", p.time_s),
            ("scan angle", p.scan_angle_rad as f64),
            ("roll", p.roll_rad as f64),
            ("pitch", p.pitch_rad as f64),
            ("heading", p.heading_rad as f64),
            ("latitude", p.lat_rad),
            ("longitude", p.lon_rad),
            ("elevation", p.elevation_m as f64),
        ];
        if let Some((name, v)) = finite.iter().find(|(_, v)| !v.is_finite()) {
            return Err(bad(format!("{name} is {v}: corrupt record")));
        }
        if let Some(r) = p.ranges_m().iter().find(|r| !(r.is_finite() && **r >= 0.0)) {
            return Err(bad(format!(
                "range {r} m is not a distance: corrupt record"
            )));
        }
        if p.lat_rad.abs() > std::f64::consts::FRAC_PI_2 {
            return Err(bad(format!(
                "latitude {} rad is beyond +-pi/2: corrupt record",
                p.lat_rad
            )));
        }
        if p.lon_rad < -TAU {
            p.lon_rad += TAU;
        } else if p.lon_rad > TAU {
            p.lon_rad -= TAU;
        }
        if p.lon_rad.abs() > TAU {
            return Err(bad(format!(
                "longitude {} rad is beyond +-4 pi: corrupt record",
                f64_le(b, 57)
            )));
        }
        Ok(p)
    }

    /// Every pulse in file order (the first bad one ends the iteration with its error).
    pub fn pulses(&self) -> impl Iterator<Item = Result<CsdPulse>> + '_ {
        (0..self.len()).map(|i| self.pulse(i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header_bytes(n: u32) -> Vec<u8> {
        let mut h = vec![0u8; CSD_HEADER_BYTES];
        h[..4].copy_from_slice(b"CSD\0");
        h[104..106].copy_from_slice(&(CSD_HEADER_BYTES as u16).to_le_bytes());
        h[124..128].copy_from_slice(&n.to_le_bytes());
        h
    }

    fn pulse_bytes(lon: f64, range: f32) -> Vec<u8> {
        let mut p = vec![0u8; CSD_PULSE_BYTES];
        p[0..8].copy_from_slice(&100.0f64.to_le_bytes());
        p[8] = 1;
        p[9..13].copy_from_slice(&range.to_le_bytes());
        p[57..65].copy_from_slice(&lon.to_le_bytes());
        p
    }

    fn write(bytes: &[u8]) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csd");
        std::fs::write(&path, bytes).unwrap();
        (dir, path)
    }

    /// Bad header, truncated file and corrupt records are refused naming the file (and the
    /// pulse); a good file reads, the longitude brought back by one turn.
    #[test]
    fn bad_inputs_are_named_and_good_pulses_read() {
        let mut good = header_bytes(2);
        good.extend(pulse_bytes(-1.0 - TAU, 800.0));
        good.extend(pulse_bytes(0.5, f32::NAN));
        let (_d, path) = write(&good);
        let f = CsdFile::open(&path).unwrap();
        assert_eq!(f.len(), 2);
        let p = f.pulse(0).unwrap();
        assert!((p.lon_rad + 1.0).abs() < 1e-12, "{}", p.lon_rad);
        assert_eq!(p.ranges_m(), &[800.0]);
        let e = f.pulse(1).unwrap_err().to_string();
        assert!(
            e.contains("t.csd") && e.contains("pulse 1") && e.contains("range"),
            "{e}"
        );

        // Truncated: one byte short of the second pulse.
        let (_d, path) = write(&good[..good.len() - 1]);
        let e = CsdFile::open(&path).unwrap_err().to_string();
        assert!(e.contains("t.csd") && e.contains("truncated"), "{e}");
        // A whole pulse missing: the header's count disagrees.
        let (_d, path) = write(&good[..good.len() - CSD_PULSE_BYTES]);
        let e = CsdFile::open(&path).unwrap_err().to_string();
        assert!(e.contains("announces 2") && e.contains("holds 1"), "{e}");
        // Shorter than the header.
        let (_d, path) = write(&good[..100]);
        let e = CsdFile::open(&path).unwrap_err().to_string();
        assert!(e.contains("shorter than the 2048-byte header"), "{e}");
        // Wrong signature.
        let mut bad = good.clone();
        bad[0] = b'X';
        let (_d, path) = write(&bad);
        let e = CsdFile::open(&path).unwrap_err().to_string();
        assert!(e.contains("not an Optech CSD file"), "{e}");
        // Header size below 2048.
        let mut bad = good.clone();
        bad[104..106].copy_from_slice(&100u16.to_le_bytes());
        let (_d, path) = write(&bad);
        let e = CsdFile::open(&path).unwrap_err().to_string();
        assert!(e.contains("header size 100"), "{e}");
    }
}
