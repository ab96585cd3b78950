//! A self-checking binary frame for records that carry tensor blobs: the journal is a sequence
//! of frames, and the item worker process answers with frames.
//!
//! Layout: `b"SPF1"`, JSON length (u32 LE), blob count (u32 LE), each blob's length (u64 LE),
//! the JSON, the blobs, then the first 8 bytes of the sha256 of everything before. A frame cut
//! short (a kill during a write) is detected and reported as [`ReadFrame::Torn`].

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use sparc3d_schema::{ErrorClass, ShardRow};
use std::io::Read;

const MAGIC: &[u8; 4] = b"SPF1";
/// Largest JSON part accepted, against garbage lengths.
const MAX_JSON: u32 = 64 << 20;
/// Largest number of blobs in one frame: the tensors, and up to 256 condition views.
const MAX_BLOBS: u32 = 64 + 256;

/// One record of a journal or of the item worker's answers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Record {
    /// First record of a journal: which shard and config it belongs to.
    Header {
        /// Shard index.
        shard: u64,
        /// Config fingerprint.
        fingerprint: String,
        /// Unix time the journal was created.
        created_at: f64,
    },
    /// An item is about to start (written and fsynced before it starts).
    Start {
        /// Item index.
        index: u64,
        /// 1-based attempt number.
        attempt: u32,
        /// Unix time.
        at: f64,
    },
    /// An item finished (ok or failed, final).
    Done {
        /// The row, tensors included.
        row: Box<ShardRow>,
        /// Unix time.
        at: f64,
    },
    /// An attempt died with a crash-class failure and will be retried.
    Crash {
        /// Item index.
        index: u64,
        /// Why it died.
        class: ErrorClass,
        /// Message.
        message: String,
        /// Unix time.
        at: f64,
    },
    /// An attempt was stopped on purpose (Ctrl-C); it does not count.
    Abort {
        /// Item index.
        index: u64,
        /// Unix time.
        at: f64,
    },
}

/// Encodes a record as a frame.
pub fn encode(record: &Record) -> Result<Vec<u8>, serde_json::Error> {
    let mut record = record.clone();
    let mut blobs: Vec<Vec<u8>> = Vec::new();
    if let Record::Done { row, .. } = &mut record {
        if let Some(t) = row.tensors.as_mut() {
            blobs = t.blobs_mut().into_iter().map(std::mem::take).collect();
        }
    }
    let json = serde_json::to_vec(&record)?;
    let body: usize = blobs.iter().map(Vec::len).sum();
    let mut out = Vec::with_capacity(16 + 8 * blobs.len() + json.len() + body + 8);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&(blobs.len() as u32).to_le_bytes());
    for b in &blobs {
        out.extend_from_slice(&(b.len() as u64).to_le_bytes());
    }
    out.extend_from_slice(&json);
    for b in &blobs {
        out.extend_from_slice(b);
    }
    let sum = Sha256::digest(&out);
    out.extend_from_slice(&sum[..8]);
    Ok(out)
}

/// The result of reading one frame.
#[derive(Debug)]
pub enum ReadFrame {
    /// A whole, valid frame and its length in bytes.
    Record(Record, u64),
    /// Clean end of input.
    End,
    /// The input ends inside a frame (a write was cut short).
    Torn,
    /// The bytes are not a valid frame.
    Corrupt(String),
}

/// Reads exactly `buf.len()` bytes; `Ok(false)` when the input ended first.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Reads the next frame.
pub fn read(r: &mut impl Read) -> std::io::Result<ReadFrame> {
    let mut head = [0u8; 12];
    let n = read_full(r, &mut head)?;
    if n == 0 {
        return Ok(ReadFrame::End);
    }
    if n < head.len() {
        return Ok(ReadFrame::Torn);
    }
    if &head[..4] != MAGIC {
        return Ok(ReadFrame::Corrupt("bad magic".into()));
    }
    let json_len = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
    let nblobs = u32::from_le_bytes([head[8], head[9], head[10], head[11]]);
    if json_len > MAX_JSON || nblobs > MAX_BLOBS {
        return Ok(ReadFrame::Corrupt(format!(
            "implausible sizes: json {json_len}, blobs {nblobs}"
        )));
    }
    let mut lens_raw = vec![0u8; 8 * nblobs as usize];
    if read_full(r, &mut lens_raw)? < lens_raw.len() {
        return Ok(ReadFrame::Torn);
    }
    let lens: Vec<u64> = lens_raw
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
        .collect();
    if lens.iter().any(|&l| l > (1 << 40)) {
        return Ok(ReadFrame::Corrupt("implausible blob length".into()));
    }
    let mut json = vec![0u8; json_len as usize];
    if read_full(r, &mut json)? < json.len() {
        return Ok(ReadFrame::Torn);
    }
    let mut blobs = Vec::with_capacity(lens.len());
    for &l in &lens {
        let mut b = vec![0u8; l as usize];
        if read_full(r, &mut b)? < b.len() {
            return Ok(ReadFrame::Torn);
        }
        blobs.push(b);
    }
    let mut sum = [0u8; 8];
    if read_full(r, &mut sum)? < sum.len() {
        return Ok(ReadFrame::Torn);
    }
    let mut h = Sha256::new();
    h.update(head);
    h.update(&lens_raw);
    h.update(&json);
    for b in &blobs {
        h.update(b);
    }
    if h.finalize()[..8] != sum {
        return Ok(ReadFrame::Corrupt("checksum mismatch".into()));
    }
    let mut record: Record = match serde_json::from_slice(&json) {
        Ok(r) => r,
        Err(e) => return Ok(ReadFrame::Corrupt(format!("json: {e}"))),
    };
    if let Record::Done { row, .. } = &mut record {
        let slots = row
            .tensors
            .as_mut()
            .map(|t| t.blobs_mut())
            .unwrap_or_default();
        if slots.len() != blobs.len() {
            return Ok(ReadFrame::Corrupt(format!(
                "{} blobs for {} tensors",
                blobs.len(),
                slots.len()
            )));
        }
        for (slot, b) in slots.into_iter().zip(blobs) {
            *slot = b;
        }
    }
    let total = 12 + lens_raw.len() as u64 + json_len as u64 + lens.iter().sum::<u64>() + 8;
    Ok(ReadFrame::Record(record, total))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparc3d_schema::{ErrorClass, RowTensors};

    fn row() -> ShardRow {
        let cubes = sparcubes::SparseCubes {
            resolution: 16,
            coords: vec![[1, 2, 3]],
            sdf: vec![0.5],
            deformation: vec![[0.0; 3]],
            cells: vec![],
            ..Default::default()
        };
        let mut r = ShardRow::failed(3, "x", "/x", 16, ErrorClass::Panic, "m".into());
        r.tensors = RowTensors::from_cubes(&cubes, 1).ok();
        r
    }

    #[test]
    fn frames_round_trip_and_detect_truncation() -> std::io::Result<()> {
        let rec = Record::Done {
            row: Box::new(row()),
            at: 1.5,
        };
        let bytes = encode(&rec).map_err(std::io::Error::other)?;
        let mut cur = std::io::Cursor::new(bytes.clone());
        match read(&mut cur)? {
            ReadFrame::Record(back, n) => {
                assert_eq!(back, rec);
                assert_eq!(n, bytes.len() as u64);
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(read(&mut cur)?, ReadFrame::End));
        let mut cut = std::io::Cursor::new(bytes[..bytes.len() - 3].to_vec());
        assert!(matches!(read(&mut cut)?, ReadFrame::Torn));
        let mut bad = bytes.clone();
        let k = bad.len() - 12;
        bad[k] ^= 1;
        assert!(matches!(
            read(&mut std::io::Cursor::new(bad))?,
            ReadFrame::Corrupt(_)
        ));
        Ok(())
    }
}
