//! The one parser of a LAS public header block (LAS 1.0-1.4, and LAZ/COPC, whose header is
//! stored uncompressed), shared by `las::inspect` (`kinescan info`: what a file says about
//! itself) and `las::read` (`kinescan tpu`: a cloud's records), and the little-endian field
//! readers and record framing constants both use. It only decodes; each caller decides what it
//! accepts (versions, formats, compression) and names the file in its errors.

/// Bytes of a LAS 1.4 public header (earlier versions have shorter ones).
pub const HEADER_1_4: usize = 375;
/// Bytes of the shortest public header (LAS 1.0-1.2).
pub const HEADER_MIN: usize = 227;
/// Bytes of a VLR header.
pub const VLR_HEADER_LEN: usize = 54;
/// Bytes of an EVLR header.
pub const EVLR_HEADER_LEN: usize = 60;
/// Bytes of an Extra Bytes descriptor (LAS 1.4 R15 Table 24).
pub const EXTRA_BYTES_DESCRIPTOR_LEN: usize = 192;

/// Little-endian u16 at byte `i` of `b`.
#[inline]
pub fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}
/// Little-endian u32 at byte `i` of `b`.
#[inline]
pub fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"))
}
/// Little-endian u64 at byte `i` of `b`.
#[inline]
pub fn u64_at(b: &[u8], i: usize) -> u64 {
    u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"))
}
/// Little-endian f64 at byte `i` of `b`.
#[inline]
pub fn f64_at(b: &[u8], i: usize) -> f64 {
    f64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"))
}
/// A fixed-size text field: up to its first NUL, trimmed.
pub fn text(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(&b[..end]).trim().to_string()
}

/// The user id (NULs trimmed) and record id of a VLR or EVLR header starting at `b[0]`.
pub fn record_ids(b: &[u8]) -> (String, u16) {
    (text(&b[2..18]), u16_at(b, 18))
}

/// The LAS 1.4 fields of the header (present when the version is 1.4 or later and the header
/// is 375 bytes or more).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Las14Fields {
    /// Start of the first EVLR (byte offset; 0 when none).
    pub evlr_start: u64,
    /// Number of EVLRs.
    pub evlr_count: u32,
    /// 64-bit number of point records.
    pub point_count: u64,
    /// 64-bit numbers of points by return 1-15.
    pub points_by_return: [u64; 15],
}

/// A decoded public header block.
#[derive(Debug, Clone, PartialEq)]
pub struct PublicHeader {
    /// Version (major, minor).
    pub version: (u8, u8),
    /// Global encoding (bit 0: adjusted standard GPS time; bit 4: WKT CRS).
    pub global_encoding: u16,
    /// System identifier.
    pub system: String,
    /// Generating software.
    pub software: String,
    /// Creation day of year and year.
    pub created: (u16, u16),
    /// Header size (bytes).
    pub header_size: usize,
    /// Offset to the point data (bytes).
    pub offset_to_points: u64,
    /// Number of VLRs.
    pub vlr_count: u32,
    /// The point data format byte as stored (bits 6-7: LASzip compression).
    pub format_byte: u8,
    /// Bytes per point record.
    pub record_len: u16,
    /// Legacy 32-bit number of point records.
    pub legacy_point_count: u64,
    /// Legacy 32-bit numbers of points by return 1-5.
    pub legacy_points_by_return: [u64; 5],
    /// Scale of X, Y, Z.
    pub scale: [f64; 3],
    /// Offset of X, Y, Z.
    pub offset: [f64; 3],
    /// Minimum X, Y, Z.
    pub min: [f64; 3],
    /// Maximum X, Y, Z.
    pub max: [f64; 3],
    /// LAS 1.4 fields.
    pub las14: Option<Las14Fields>,
}

impl PublicHeader {
    /// Decodes the header at the start of `head` (at least [`HEADER_MIN`] bytes, and the 1.4
    /// fields when [`HEADER_1_4`] are given); `None` without the `LASF` signature or with too
    /// few bytes.
    pub fn parse(head: &[u8]) -> Option<PublicHeader> {
        if head.len() < HEADER_MIN || !head.starts_with(b"LASF") {
            return None;
        }
        let version = (head[24], head[25]);
        let header_size = usize::from(u16_at(head, 94));
        let xyz = |at: usize| [0, 1, 2].map(|k| f64_at(head, at + 8 * k));
        let las14 = (version >= (1, 4) && header_size >= HEADER_1_4 && head.len() >= HEADER_1_4)
            .then(|| Las14Fields {
                evlr_start: u64_at(head, 235),
                evlr_count: u32_at(head, 243),
                point_count: u64_at(head, 247),
                points_by_return: std::array::from_fn(|k| u64_at(head, 255 + 8 * k)),
            });
        Some(PublicHeader {
            version,
            global_encoding: u16_at(head, 6),
            system: text(&head[26..58]),
            software: text(&head[58..90]),
            created: (u16_at(head, 90), u16_at(head, 92)),
            header_size,
            offset_to_points: u64::from(u32_at(head, 96)),
            vlr_count: u32_at(head, 100),
            format_byte: head[104],
            record_len: u16_at(head, 105),
            legacy_point_count: u64::from(u32_at(head, 107)),
            legacy_points_by_return: std::array::from_fn(|k| u64::from(u32_at(head, 111 + 4 * k))),
            scale: xyz(131),
            offset: xyz(155),
            min: [f64_at(head, 187), f64_at(head, 203), f64_at(head, 219)],
            max: [f64_at(head, 179), f64_at(head, 195), f64_at(head, 211)],
            las14,
        })
    }

    /// Point data record format (0-10), without the compression bits.
    pub fn point_format(&self) -> u8 {
        self.format_byte & 0x3f
    }

    /// Whether the points are LASzip-compressed (format byte bit 7 or 6).
    pub fn compressed(&self) -> bool {
        self.format_byte & 0xC0 != 0
    }

    /// Number of point records: the 64-bit count of LAS 1.4, the legacy count when that is 0
    /// (or before 1.4).
    pub fn point_count(&self) -> u64 {
        match self.las14 {
            Some(f) if f.point_count != 0 => f.point_count,
            _ => self.legacy_point_count,
        }
    }

    /// Points by return (1-15 for LAS 1.4, 1-5 before).
    pub fn points_by_return(&self) -> Vec<u64> {
        match self.las14 {
            Some(f) => f.points_by_return.to_vec(),
            None => self.legacy_points_by_return.to_vec(),
        }
    }

    /// (start, count) of the EVLRs ((0, 0) before LAS 1.4).
    pub fn evlrs(&self) -> (u64, u32) {
        self.las14.map_or((0, 0), |f| (f.evlr_start, f.evlr_count))
    }
}
