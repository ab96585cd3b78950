//! The content digest of rows: a sha256 over every column except the run-dependent ones
//! (timings, attempts, captured stderr), so that two runs of the same job agree whatever the
//! number of workers or interruptions.

use crate::hex::hex;
use crate::row::ShardRow;
use sha2::{Digest, Sha256};

fn field(h: &mut Sha256, bytes: &[u8]) {
    h.update((bytes.len() as u64).to_le_bytes());
    h.update(bytes);
}

fn opt(h: &mut Sha256, v: Option<&[u8]>) {
    match v {
        Some(b) => {
            h.update([1]);
            field(h, b);
        }
        None => h.update([0]),
    }
}

/// Feeds one row's content into a hasher.
pub fn update_row(h: &mut Sha256, row: &ShardRow) {
    h.update(row.item_index.to_le_bytes());
    field(h, row.id.as_bytes());
    field(h, row.uri.as_bytes());
    opt(h, row.source_sha256.as_deref().map(str::as_bytes));
    field(h, row.status.as_str().as_bytes());
    opt(h, row.error_class.map(|c| c.as_str().as_bytes()));
    opt(h, row.error_message.as_deref().map(str::as_bytes));
    h.update(row.resolution.to_le_bytes());
    match &row.normalization {
        Some(n) => {
            h.update([1]);
            for x in n.center {
                h.update(x.to_le_bytes());
            }
            h.update(n.scale.to_le_bytes());
        }
        None => h.update([0]),
    }
    match &row.counts {
        Some(k) => {
            h.update([1]);
            for v in crate::arrow::count_values(k) {
                opt(h, v.map(|x| x.to_le_bytes()).as_ref().map(|b| &b[..]));
            }
        }
        None => h.update([0]),
    }
    match &row.tensors {
        Some(t) => {
            h.update([1]);
            for (stem, tensor) in t.iter() {
                // Absent samples leave the digest as it was before sample columns existed.
                if tensor.is_none() && crate::columns::SAMPLE_TENSORS.contains(&stem) {
                    continue;
                }
                field(h, stem.as_bytes());
                match tensor {
                    Some(t) => {
                        h.update([1]);
                        field(h, t.dtype.as_str().as_bytes());
                        for d in &t.shape {
                            h.update(d.to_le_bytes());
                        }
                        field(h, &t.blob);
                    }
                    None => h.update([0]),
                }
            }
        }
        None => h.update([0]),
    }
    // Rows without appearance facts leave the digest as it was before they existed (their
    // attribute tensors are in `tensors` above, only where present).
    if let Some(a) = &row.appearance {
        field(h, b"appearance");
        h.update(a.materials.to_le_bytes());
        h.update(a.textures.to_le_bytes());
        h.update(a.texture_max_size.to_le_bytes());
        field(h, a.alpha_modes.join(",").as_bytes());
        h.update([u8::from(a.vertex_colors)]);
        field(h, a.not_read.join("\n").as_bytes());
        h.update(a.nearest_cells.to_le_bytes());
    }
    // Rows without quality facts leave the digest as it was before they existed; the derived
    // columns (`aspect`, `shell_share`) follow from what is hashed here and in the counts.
    if let Some(q) = &row.quality {
        field(h, b"quality");
        for v in [
            q.boundary_edges,
            q.non_manifold_edges,
            q.degenerate_faces,
            q.duplicate_faces,
            q.sealed_pockets,
        ] {
            h.update(v.to_le_bytes());
        }
        for x in q.extent {
            h.update(x.to_le_bytes());
        }
        h.update(q.surface_area.to_le_bytes());
        opt(
            h,
            q.output_volume
                .map(f64::to_le_bytes)
                .as_ref()
                .map(|b| &b[..]),
        );
        opt(
            h,
            q.output_components
                .map(u64::to_le_bytes)
                .as_ref()
                .map(|b| &b[..]),
        );
    }
    // Rows without a signature (failed, or written before it existed) digest as before it.
    if let Some(s) = &row.shape_signature {
        field(h, crate::columns::SHAPE_SIGNATURE.as_bytes());
        for x in s {
            h.update(x.to_le_bytes());
        }
    }
    // Rows without renders digest as before they existed; each view's seconds are run-
    // dependent, like the timings, and left out.
    if let Some(r) = row.tensors.as_ref().and_then(|t| t.renders.as_ref()) {
        field(h, crate::columns::RENDER_VIEWS.as_bytes());
        h.update((r.views.len() as u64).to_le_bytes());
        for v in &r.views {
            field(h, &v.png);
        }
        field(h, r.transforms.as_bytes());
        // Views that drew all of the appearance digest as before the column existed.
        if !r.not_read.is_empty() {
            field(h, crate::columns::RENDER_NOT_READ.as_bytes());
            for entry in &r.not_read {
                field(h, entry.as_bytes());
            }
        }
    }
    // Rows without provenance leave the digest as it was before provenance columns existed.
    if !row.provenance.is_empty() {
        field(h, crate::columns::PROVENANCE_PREFIX.as_bytes());
        h.update((row.provenance.len() as u64).to_le_bytes());
        for (name, value) in &row.provenance {
            field(h, name.as_bytes());
            field(h, value.as_bytes());
        }
    }
}

/// Hex content digest of rows in the given order.
pub fn rows_digest(rows: &[ShardRow]) -> String {
    let mut h = Sha256::new();
    for r in rows {
        update_row(&mut h, r);
    }
    hex(&h.finalize())
}

/// Hex digest of shard digests in shard order: the content digest of a whole job.
pub fn combine(digests: &[String]) -> String {
    let mut h = Sha256::new();
    for d in digests {
        field(&mut h, d.as_bytes());
    }
    hex(&h.finalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digest_ignores_run_dependent_columns_only() {
        let rows = crate::arrow::tests::sample_rows();
        let d = rows_digest(&rows);
        let mut other = rows.clone();
        other[0].timings.total_s = 99.0;
        other[0].attempts = 3;
        other[1].stderr_tail = None;
        assert_eq!(rows_digest(&other), d);
        other[1].error_message = Some("different".into());
        assert_ne!(rows_digest(&other), d);
        let mut with = rows.clone();
        with[0].provenance.insert("license".into(), "cc0".into());
        let with_digest = rows_digest(&with);
        assert_ne!(with_digest, d);
        with[0].provenance.insert("license".into(), "cc-by".into());
        assert_ne!(rows_digest(&with), with_digest);
    }
}
