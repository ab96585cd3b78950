//! The render columns of a shard (only in the shards of a job with `[renders]`): each ok
//! item's condition views as PNG files, the seconds each took to trace and the views'
//! `transforms.json` (docs/FORMAT.md, "Renders"; docs/RENDERS.md). A shard of any other job
//! has no such columns and reads as rows without renders.

use crate::columns as c;
use crate::error::{Result, SchemaError};
use crate::row::{RenderedView, RowRenders, ShardRow};
use arrow_array::builder::{LargeBinaryBuilder, ListBuilder};
use arrow_array::types::Float64Type;
use arrow_array::{
    Array, ArrayRef, Float64Array, LargeBinaryArray, ListArray, RecordBatch, StringArray,
};
use arrow_schema::{DataType, Field};
use std::sync::Arc;

/// The render columns' fields, in order: views (`list<large_binary>`, a PNG each), seconds
/// (`list<float64>`), `transforms.json` and what was not read (`utf8`); null in rows without
/// renders.
pub fn fields() -> Vec<Field> {
    let png = Arc::new(Field::new("item", DataType::LargeBinary, true));
    let seconds = Arc::new(Field::new("item", DataType::Float64, true));
    vec![
        Field::new(c::RENDER_VIEWS, DataType::List(png), true),
        Field::new(c::RENDER_SECONDS, DataType::List(seconds), true),
        Field::new(c::RENDER_TRANSFORMS, DataType::Utf8, true),
        Field::new(c::RENDER_NOT_READ, DataType::Utf8, true),
    ]
}

fn renders_of(row: &ShardRow) -> Option<&RowRenders> {
    row.tensors.as_ref()?.renders.as_ref()
}

/// The render columns of `rows`, in the order of [`fields`].
pub fn columns(rows: &[ShardRow]) -> Vec<ArrayRef> {
    let mut views = ListBuilder::new(LargeBinaryBuilder::new()).with_field(Arc::new(Field::new(
        "item",
        DataType::LargeBinary,
        true,
    )));
    for r in rows.iter().map(renders_of) {
        match r {
            Some(r) => {
                for v in &r.views {
                    views.values().append_value(&v.png);
                }
                views.append(true);
            }
            None => views.append(false),
        }
    }
    let seconds = ListArray::from_iter_primitive::<Float64Type, _, _>(rows.iter().map(|row| {
        renders_of(row).map(|r| r.views.iter().map(|v| Some(v.seconds)).collect::<Vec<_>>())
    }));
    let transforms: Vec<Option<&str>> = rows
        .iter()
        .map(|row| renders_of(row).map(|r| r.transforms.as_str()))
        .collect();
    let not_read: Vec<Option<String>> = rows
        .iter()
        .map(|row| renders_of(row).map(|r| r.not_read.join("\n")))
        .collect();
    vec![
        Arc::new(views.finish()),
        Arc::new(seconds),
        Arc::new(StringArray::from(transforms)),
        Arc::new(StringArray::from(not_read)),
    ]
}

/// The renders of row `i` of a batch: `None` when the batch has no render columns (a job
/// without `[renders]`) or the row none; an error when the columns disagree.
pub fn renders_at(batch: &RecordBatch, i: usize) -> Result<Option<RowRenders>> {
    let Some(views) = batch.column_by_name(c::RENDER_VIEWS) else {
        return Ok(None);
    };
    let wrong = |name: &str, reason: String| SchemaError::Column {
        name: name.into(),
        reason,
    };
    let list = |name: &str, a: &ArrayRef| -> Result<ListArray> {
        a.as_any()
            .downcast_ref::<ListArray>()
            .cloned()
            .ok_or_else(|| wrong(name, "not a list".into()))
    };
    let views = list(c::RENDER_VIEWS, views)?;
    if !views.is_valid(i) {
        return Ok(None);
    }
    let seconds = batch
        .column_by_name(c::RENDER_SECONDS)
        .ok_or_else(|| wrong(c::RENDER_SECONDS, "missing beside render_views".into()))?;
    let seconds = list(c::RENDER_SECONDS, seconds)?;
    let transforms = batch
        .column_by_name(c::RENDER_TRANSFORMS)
        .and_then(|a| a.as_any().downcast_ref::<StringArray>())
        .filter(|a| a.is_valid(i))
        .ok_or_else(|| wrong(c::RENDER_TRANSFORMS, format!("no transforms in row {i}")))?;
    let pngs = views.value(i);
    let pngs = pngs
        .as_any()
        .downcast_ref::<LargeBinaryArray>()
        .ok_or_else(|| wrong(c::RENDER_VIEWS, "views are not large_binary".into()))?;
    let secs = seconds.value(i);
    let secs = secs
        .as_any()
        .downcast_ref::<Float64Array>()
        .filter(|s| s.len() == pngs.len())
        .ok_or_else(|| {
            wrong(
                c::RENDER_SECONDS,
                format!("row {i}: not one float64 a view ({} views)", pngs.len()),
            )
        })?;
    let views = (0..pngs.len())
        .map(|v| RenderedView {
            png: pngs.value(v).to_vec(),
            seconds: secs.value(v),
        })
        .collect();
    Ok(Some(RowRenders {
        views,
        transforms: transforms.value(i).to_string(),
        not_read: not_read_at(batch, i),
    }))
}

/// Row `i`'s `render_not_read` entries: none when the column is absent (a shard written
/// before it) or empty.
fn not_read_at(batch: &RecordBatch, i: usize) -> Vec<String> {
    batch
        .column_by_name(c::RENDER_NOT_READ)
        .and_then(|a| a.as_any().downcast_ref::<StringArray>())
        .filter(|a| a.is_valid(i))
        .map(|a| a.value(i))
        .filter(|text| !text.is_empty())
        .map_or(Vec::new(), |text| {
            text.split('\n').map(str::to_string).collect()
        })
}

#[cfg(test)]
mod tests {
    use crate::arrow::tests::sample_rows;
    use crate::arrow::{batch_to_rows, rows_to_batch, rows_to_batch_for, schema, Sections};
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
            crate::digest::rows_digest(&rows)
        };
        let with = |png, seconds, transforms| with_not_read(png, seconds, transforms, &[]);
        let base = with(vec![1, 2, 3], 0.5, "{}");
        assert_eq!(with(vec![1, 2, 3], 9.0, "{}"), base);
        assert_ne!(with(vec![1, 2, 4], 0.5, "{}"), base);
        assert_ne!(with(vec![1, 2, 3], 0.5, "{ }"), base);
        assert_ne!(crate::digest::rows_digest(&sample_rows()), base);
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
