//! The output copy: every record of the cloud with its bytes unchanged, extra dimensions of the
//! cloud named like ours dropped (the report lists them), ours appended; the header, every VLR
//! (the Extra Bytes VLR rewritten: the cloud's descriptors kept, ours appended), the bytes
//! between the VLRs and the points, and every EVLR (and LAS 1.3 waveform data) byte for byte.
//! The header changes only where the layout moved: record length, offset to the points,
//! number of VLRs (+1 when the cloud had no Extra Bytes VLR), start of the EVLRs and of the
//! waveform data.

use crate::io::las::read::{core_record_len, LasInput, EXTRA_BYTES_DESCRIPTOR_LEN};
use crate::io::las::{extra_bytes_descriptor, ExtraDim};
use crate::{Error, Result};
use std::ops::Range;

/// How records of the cloud become records of the output.
#[derive(Debug, Clone)]
pub struct OutputLayout {
    /// Byte ranges of an input record copied, in order.
    pub keep: Vec<Range<usize>>,
    /// Bytes kept per record.
    pub kept_len: usize,
    /// Our dimensions and their byte offsets in the output record.
    pub added: Vec<(ExtraDim, usize)>,
    /// Output record length.
    pub record_len: usize,
    /// Names of the cloud's dimensions replaced.
    pub replaced: Vec<String>,
    /// Header, VLRs and the bytes up to the points, as written.
    pub prefix: Vec<u8>,
    /// Where the cloud's bytes after its points start (EVLRs, waveform data).
    pub tail_from: usize,
}

/// A VLR header (54 bytes).
fn vlr_header(user_id: &str, record_id: u16, len: usize, description: &str) -> Vec<u8> {
    let mut v = vec![0u8; 54];
    v[2..2 + user_id.len()].copy_from_slice(user_id.as_bytes());
    v[18..20].copy_from_slice(&record_id.to_le_bytes());
    v[20..22].copy_from_slice(&(len as u16).to_le_bytes());
    v[22..22 + description.len()].copy_from_slice(description.as_bytes());
    v
}

impl OutputLayout {
    /// The layout for appending `dims` to `input`'s records.
    pub fn new(input: &LasInput, dims: &[ExtraDim]) -> Result<OutputLayout> {
        let b = input.bytes();
        let core = core_record_len(input.point_format).expect("checked on open");
        let ours = |name: &str| dims.iter().any(|d| d.name == name);
        // Record bytes kept: the core, the cloud's dimensions not named like ours, then any
        // bytes its Extra Bytes VLR does not describe.
        let mut keep: Vec<Range<usize>> = Vec::new();
        keep.push(0..core);
        let mut descriptors = Vec::new();
        let mut replaced = Vec::new();
        let mut described = 0;
        for d in &input.extra_dims {
            described = d.offset + d.size;
            if ours(&d.name) {
                replaced.push(d.name.clone());
                continue;
            }
            let r = core + d.offset..core + d.offset + d.size;
            match keep.last_mut() {
                Some(last) if last.end == r.start => last.end = r.end,
                _ => keep.push(r),
            }
            descriptors.extend_from_slice(&d.descriptor);
        }
        let undescribed = input.record_len - core - described;
        if undescribed > 0 {
            let r = core + described..input.record_len;
            match keep.last_mut() {
                Some(last) if last.end == r.start => last.end = r.end,
                _ => keep.push(r),
            }
            // Undocumented bytes (data type 0, options = their count) so ours stay aligned.
            for chunk in 0..undescribed.div_ceil(255) {
                let n = (undescribed - chunk * 255).min(255);
                let mut d = [0u8; EXTRA_BYTES_DESCRIPTOR_LEN];
                d[3] = n as u8;
                let name = format!("undescribed_{chunk}");
                d[4..4 + name.len()].copy_from_slice(name.as_bytes());
                descriptors.extend_from_slice(&d);
            }
        }
        let kept_len: usize = keep.iter().map(|r| r.len()).sum();
        let mut added = Vec::new();
        let mut at = kept_len;
        for d in dims {
            descriptors.extend_from_slice(&extra_bytes_descriptor(d));
            added.push((d.clone(), at));
            at += d.data_type.size();
        }
        let record_len = at;
        if record_len > usize::from(u16::MAX) || descriptors.len() > usize::from(u16::MAX) {
            return Err(Error::bad_file(
                input.path(),
                "records with the uncertainty dimensions exceed the LAS limits (65535 B)",
            ));
        }
        // VLRs: the Extra Bytes VLR replaced in place or appended.
        let extra_at = input
            .vlrs
            .iter()
            .position(|v| v.user_id == "LASF_Spec" && v.record_id == 4);
        if extra_at.is_none() && input.find_vlr("LASF_Spec", 4).is_some() {
            return Err(Error::bad_file(
                input.path(),
                "the Extra Bytes descriptors are in an EVLR: not supported, move them to a VLR",
            ));
        }
        let mut extra_vlr = vlr_header("LASF_Spec", 4, descriptors.len(), "Extra Bytes");
        extra_vlr.extend_from_slice(&descriptors);
        let mut prefix = b[..input.header_size].to_vec();
        for (k, v) in input.vlrs.iter().enumerate() {
            if Some(k) == extra_at {
                prefix.extend_from_slice(&extra_vlr);
            } else {
                prefix.extend_from_slice(&b[v.bytes.clone()]);
            }
        }
        if extra_at.is_none() {
            prefix.extend_from_slice(&extra_vlr);
        }
        let vlr_end = input.vlrs.last().map_or(input.header_size, |v| v.bytes.end);
        prefix.extend_from_slice(&b[vlr_end..input.offset_to_points]);
        // Header fields that moved.
        let offset_to_points = prefix.len();
        let n_vlrs = input.vlrs.len() + usize::from(extra_at.is_none());
        let old_end = input.offset_to_points as u64 + input.point_count * input.record_len as u64;
        let new_end = offset_to_points as u64 + input.point_count * record_len as u64;
        let to_u32 = |v: usize| {
            u32::try_from(v).map_err(|_| Error::bad_file(input.path(), "VLRs beyond 4 GiB"))
        };
        prefix[96..100].copy_from_slice(&to_u32(offset_to_points)?.to_le_bytes());
        prefix[100..104].copy_from_slice(&to_u32(n_vlrs)?.to_le_bytes());
        prefix[105..107].copy_from_slice(&(record_len as u16).to_le_bytes());
        let moved = |old: u64| {
            if old >= old_end {
                old - old_end + new_end
            } else {
                old
            }
        };
        let u64_at = |h: &[u8], i: usize| u64::from_le_bytes(h[i..i + 8].try_into().expect("8"));
        if input.version.1 >= 3 {
            let w = u64_at(&prefix, 227);
            if w != 0 {
                prefix[227..235].copy_from_slice(&moved(w).to_le_bytes());
            }
        }
        if input.version.1 >= 4 && !input.evlrs.is_empty() {
            let e = u64_at(&prefix, 235);
            prefix[235..243].copy_from_slice(&moved(e).to_le_bytes());
        }
        Ok(OutputLayout {
            keep,
            kept_len,
            added,
            record_len,
            replaced,
            prefix,
            tail_from: old_end as usize,
        })
    }

    /// Copies the kept bytes of input record `rec` into output record `out`.
    #[inline]
    pub fn copy_kept(&self, rec: &[u8], out: &mut [u8]) {
        let mut at = 0;
        for r in &self.keep {
            out[at..at + r.len()].copy_from_slice(&rec[r.clone()]);
            at += r.len();
        }
    }
}
