//! The render columns of a shard (only in the shards of a job with `[renders]`): each ok
//! item's condition views as PNG files, the seconds each took to trace and the views'
//! `transforms.json` (docs/FORMAT.md, "Renders"; docs/RENDERS.md). A shard of any other job
//! has no such columns and reads as rows without renders.

use crate::columns as c;
use crate::columns::table::Kind::{Blobs, F64s, Lines, Text};
use crate::columns::table::Role::{Added, Always, Run};
use crate::columns::table::{stored, Column, Group, Scalar, Value};
use crate::row::{RenderedView, RowRenders};

/// The render columns, in column order: views (`list<large_binary>`, a PNG each), seconds
/// (`list<float64>`, one a view), `transforms.json` (`utf8`) and what was not read (`utf8`,
/// one entry a line; added after the group's first shards, so a shard without it reads as
/// views that drew everything); null in rows without renders. The digest feeds the views'
/// bytes, the transforms and what was not read, never the seconds (run-dependent). The
/// evolution rule is [`crate::columns::table`]'s.
pub static RENDERS: Group<RowRenders> = Group {
    tag: c::RENDER_VIEWS,
    of: |row| row.tensors.as_ref()?.renders.as_ref(),
    columns: &[
        Column {
            name: c::RENDER_VIEWS,
            kind: Blobs,
            role: Always(0),
            get: |_, r| {
                Some(Value::Blobs(
                    r.views.iter().map(|v| v.png.clone()).collect(),
                ))
            },
            set: Some(|r, v| {
                let pngs = Vec::<Vec<u8>>::from_value(v)?;
                r.views = pngs
                    .into_iter()
                    .map(|png| RenderedView { png, seconds: 0.0 })
                    .collect();
                Some(())
            }),
        },
        Column {
            name: c::RENDER_SECONDS,
            kind: F64s,
            role: Run,
            get: |_, r| Some(Value::F64s(r.views.iter().map(|v| v.seconds).collect())),
            // After the views (column order): one float a view, or the row is refused.
            set: Some(|r, v| {
                let seconds = Vec::<f64>::from_value(v).filter(|s| s.len() == r.views.len())?;
                for (view, s) in r.views.iter_mut().zip(seconds) {
                    view.seconds = s;
                }
                Some(())
            }),
        },
        stored!(c::RENDER_TRANSFORMS, Text, Always(1), transforms),
        stored!(c::RENDER_NOT_READ, Lines, Added, not_read),
    ],
};

#[cfg(test)]
mod tests {
    use crate::columns::arrow::tests::sample_rows;
    use crate::columns::arrow::{
        batch_to_rows, rows_to_batch, rows_to_batch_for, schema, Sections,
    };
    use crate::row::{RenderedView, RowRenders};

    #[test]
    fn renders_round_trip_and_a_job_without_them_has_no_columns() -> crate::Result<()> {
        let mut rows = sample_rows();
        let renders = RowRenders {
            views: (0..3)
                .map(|v| RenderedView {
                    png: vec![v as u8; 10 + v],
                    seconds: 0.25 * v as f64,
                })
                .collect(),
            transforms: "{\"frames\": []}".into(),
            not_read: vec![
                "texture a.png: not found".into(),
                "texture b.png: too large".into(),
            ],
        };
        if let Some(t) = rows[0].tensors.as_mut() {
            t.renders = Some(renders.clone());
        }
        let on = Sections {
            renders: true,
            ..Sections::default()
        };
        let batch = rows_to_batch_for(&rows, &[], on)?;
        assert!(batch.column_by_name("render_views").is_some());
        let back = batch_to_rows(&batch)?;
        assert_eq!(
            back[0].tensors.as_ref().and_then(|t| t.renders.clone()),
            Some(renders)
        );
        assert_eq!(back, rows);
        // Without the section: the plain schema, and the rows read back without renders.
        let plain = rows_to_batch(&rows)?;
        assert_eq!(plain.schema(), schema());
        let back = batch_to_rows(&plain)?;
        assert!(back[0]
            .tensors
            .as_ref()
            .is_some_and(|t| t.renders.is_none()));
        Ok(())
    }

    #[test]
    fn the_digest_covers_each_views_bytes_and_transforms_but_not_its_seconds() {
        let with_not_read = |png: Vec<u8>, seconds: f64, transforms: &str, not_read: &[&str]| {
            let mut rows = sample_rows();
            if let Some(t) = rows[0].tensors.as_mut() {
                t.renders = Some(RowRenders {
                    views: vec![RenderedView { png, seconds }],
                    transforms: transforms.into(),
                    not_read: not_read.iter().map(|s| s.to_string()).collect(),
                });
            }
            crate::row::digest::rows_digest(&rows)
        };
        let with = |png, seconds, transforms| with_not_read(png, seconds, transforms, &[]);
        let base = with(vec![1, 2, 3], 0.5, "{}");
        assert_eq!(with(vec![1, 2, 3], 9.0, "{}"), base);
        assert_ne!(with(vec![1, 2, 4], 0.5, "{}"), base);
        assert_ne!(with(vec![1, 2, 3], 0.5, "{ }"), base);
        assert_ne!(crate::row::digest::rows_digest(&sample_rows()), base);
        let missing = with_not_read(vec![1, 2, 3], 0.5, "{}", &["texture a.png: not found"]);
        assert_ne!(missing, base);
    }

    #[test]
    fn a_shard_written_before_render_not_read_reads_with_nothing_named() -> crate::Result<()> {
        let mut rows = sample_rows();
        if let Some(t) = rows[0].tensors.as_mut() {
            t.renders = Some(RowRenders {
                views: vec![RenderedView {
                    png: vec![7; 4],
                    seconds: 0.1,
                }],
                transforms: "{}".into(),
                not_read: vec!["texture a.png: not found".into()],
            });
        }
        let on = Sections {
            renders: true,
            ..Sections::default()
        };
        let batch = rows_to_batch_for(&rows, &[], on)?;
        let keep: Vec<usize> = (0..batch.num_columns())
            .filter(|&i| batch.schema().field(i).name() != "render_not_read")
            .collect();
        let older = batch.project(&keep).map_err(crate::SchemaError::Arrow)?;
        let back = batch_to_rows(&older)?;
        let renders = back[0].tensors.as_ref().and_then(|t| t.renders.as_ref());
        assert_eq!(renders.map(|r| r.not_read.len()), Some(0));
        assert_eq!(renders.map(|r| r.views.len()), Some(1));
        Ok(())
    }
}
