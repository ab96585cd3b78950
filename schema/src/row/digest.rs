//! The content digest of rows: a sha256 over every column except the run-dependent ones
//! (timings, attempts, captured stderr), so that two runs of the same job agree whatever the
//! number of workers or interruptions.

use crate::columns::table::{Group, Kind, Role, Value};
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

/// Feeds a row's facts of `g`, when it has them, in the order and the way the group's table
/// says ([`Group::fed`], [`Role`]): its tag, then each fed column.
pub(crate) fn group<F: Default>(h: &mut Sha256, g: &Group<F>, row: &ShardRow) {
    let Some(facts) = (g.of)(row) else {
        return;
    };
    field(h, g.tag.as_bytes());
    for c in g.fed() {
        let value = (c.get)(row, facts);
        match (c.role, value) {
            (Role::Always(_), Some(v)) => bare(h, c.kind, &v),
            (Role::Nullable(_), v) => opt(h, v.map(|v| bytes(c.kind, &v)).as_deref()),
            (Role::Added, Some(v)) if !is_empty(&v) => {
                field(h, c.name.as_bytes());
                bare(h, c.kind, &v);
            }
            _ => {}
        }
    }
}

/// A value's bytes: little-endian numbers, one byte a bool, the joined text of entries.
fn bytes(kind: Kind, v: &Value) -> Vec<u8> {
    match v {
        Value::U32(x) => x.to_le_bytes().to_vec(),
        Value::U64(x) => x.to_le_bytes().to_vec(),
        Value::F64(x) => x.to_le_bytes().to_vec(),
        Value::Bool(b) => vec![u8::from(*b)],
        Value::Entries(e) => match kind {
            Kind::Joined(sep) => e.join(&sep.to_string()).into_bytes(),
            _ => e.concat().into_bytes(),
        },
        Value::F32s(s) => s.iter().flat_map(|x| x.to_le_bytes()).collect(),
        Value::F64s(s) => s.iter().flat_map(|x| x.to_le_bytes()).collect(),
        Value::Text(t) => t.as_bytes().to_vec(),
        Value::Blobs(b) => b.concat(),
    }
}

/// Feeds a value bare: its bytes, length-prefixed for text (whose length varies); the entries
/// of a [`Kind::Lines`] column one by one; blobs as their count, then each.
fn bare(h: &mut Sha256, kind: Kind, v: &Value) {
    match (kind, v) {
        (Kind::Lines, Value::Entries(e)) => e.iter().for_each(|x| field(h, x.as_bytes())),
        (_, Value::Blobs(b)) => {
            h.update((b.len() as u64).to_le_bytes());
            b.iter().for_each(|x| field(h, x));
        }
        (_, Value::Entries(_) | Value::Text(_)) => field(h, &bytes(kind, v)),
        _ => h.update(bytes(kind, v)),
    }
}

/// Whether a value holds nothing (no entries, no floats): an added column feeds it as absent.
fn is_empty(v: &Value) -> bool {
    match v {
        Value::Entries(e) => e.is_empty(),
        Value::F32s(s) => s.is_empty(),
        Value::F64s(s) => s.is_empty(),
        Value::Blobs(b) => b.is_empty(),
        Value::Text(t) => t.is_empty(),
        _ => false,
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
            for v in crate::columns::arrow::count_values(k) {
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
    // The optional groups declared in tables (crate::columns::table): a row without a group
    // digests as before the group existed.
    group(h, &crate::columns::attributes::FACTS, row);
    group(h, &crate::columns::quality::QUALITY, row);
    group(h, &crate::columns::signature::SIGNATURE, row);
    group(h, &crate::columns::renders::RENDERS, row);
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
        let rows = crate::columns::arrow::tests::sample_rows();
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

#[cfg(test)]
mod pinned {
    use super::rows_digest;
    use crate::row::quality::QualityFacts;
    use crate::row::{AppearanceFacts, RenderedView, RowRenders, ShardRow};

    /// Sample rows whose ok row has each group `groups` names (`a`ppearance, `q`uality,
    /// `s`ignature, `r`enders).
    fn rows_with(groups: &str) -> Vec<ShardRow> {
        let mut rows = crate::columns::arrow::tests::sample_rows();
        let ok = &mut rows[0];
        if groups.contains('a') {
            ok.appearance = Some(AppearanceFacts {
                materials: 2,
                textures: 1,
                texture_max_size: 512,
                alpha_modes: vec!["MASK".into(), "OPAQUE".into()],
                vertex_colors: true,
                not_read: vec!["material 0: normal texture".into(), "image 1".into()],
                nearest_cells: 3,
            });
        }
        if groups.contains('q') {
            ok.quality = Some(QualityFacts {
                boundary_edges: 4,
                non_manifold_edges: 1,
                degenerate_faces: 2,
                duplicate_faces: 3,
                extent: [2.0, 1.0, 0.5],
                surface_area: 7.25,
                output_volume: Some(0.125),
                output_components: None,
                sealed_pockets: 5,
            });
        }
        if groups.contains('s') {
            ok.shape_signature = Some((0..32).map(|i| i as f32 / 8.0 - 1.0).collect());
        }
        if groups.contains('r') {
            if let Some(t) = ok.tensors.as_mut() {
                t.renders = Some(RowRenders {
                    views: vec![RenderedView {
                        png: vec![1, 2, 3],
                        seconds: 0.5,
                    }],
                    transforms: "{}".into(),
                    not_read: vec!["texture a.png: not found".into()],
                });
            }
        }
        rows
    }

    /// Every group's feed, pinned to the digests the hand-written feeds gave before the
    /// groups' tables (`crate::columns::table`) existed: the stored digest of every shard
    /// written since recomputes the same.
    #[test]
    fn every_groups_feed_is_pinned() {
        let digests: Vec<(&str, String)> = ["", "a", "q", "s", "r", "aqsr"]
            .into_iter()
            .map(|g| (g, rows_digest(&rows_with(g))))
            .collect();
        let pinned = [
            (
                "",
                "0aa7e5b3284caf3716240acdc3b531ae00a83cf38dd61576410191a5caf19d49",
            ),
            (
                "a",
                "1956d24c6ff211e237a2cf7f4aab07878f30ab610b6c36959e13a210779324ba",
            ),
            (
                "q",
                "798c2ff506038e9e61123676f0f1be5ad6f8a463e356d1180f3e91d701b3506c",
            ),
            (
                "s",
                "3466f2ed7dbccfe34074ba8e510d25d055c2f616976a60ae042db51034a4bc9e",
            ),
            (
                "r",
                "dcdb84571c193c979f577b913adb9b86e64d31fb16eb2feb8d7bac19ab5a17a5",
            ),
            (
                "aqsr",
                "2f774aacbc6ecd6dd79cdd9d0edcf44cab765a4d8dff7bb6fa4f81491ed8af56",
            ),
        ];
        let found: Vec<(&str, &str)> = digests.iter().map(|(g, d)| (*g, d.as_str())).collect();
        assert_eq!(found, pinned);
    }
}
