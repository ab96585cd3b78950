//! The items of an export: the wanted ok rows read from the job's shards (only the columns
//! the consumer reads), each made into the consumer's files in parallel, and written in
//! manifest order by one writer (`sparc3d_formats::export`).

use crate::rows::export_name::ExportNames;
use crate::rows::row_filter::RowFilter;
use anyhow::{Context, Result};
use rayon::prelude::*;
use sparc3d_formats::export::{ItemOutcome, Outcome, Staging, Written};
use sparc3d_formats::{Consumer, Frame, Item, StoredSamples};
use sparc3d_manifests::source_id::names_files_of;
use sparc3d_schema::ShardRow;
use sparc3d_workers::store::read::{for_each_shard_row, Columns};
use sparc3d_workers::store::state::Check;
use sparc3d_workers::Job;
use std::collections::BTreeSet;

/// Which ok items an export takes: those `--ids` names (all when empty) that pass `--where`.
pub(super) struct Chosen<'a> {
    /// The ids `--ids` named; every ok item when empty.
    pub ids: &'a BTreeSet<String>,
    /// `--where`'s filter.
    pub filter: Option<&'a RowFilter>,
}

/// Writes every wanted ok item's files into `staging`; an item that fails is named on stderr
/// and the rest go on. Errors only when a shard cannot be read or a file cannot be written.
///
/// Items are computed in parallel batches of twice the pool's threads (so a slow item does
/// not leave the other threads idle for long) while one writer thread writes the previous
/// batches' files in manifest order; at most two batches' files are in memory.
pub(super) fn write_items(
    job: &Job,
    consumer: Consumer,
    frame: Frame,
    wanted: &Chosen,
    staging: &Staging,
) -> Result<Written> {
    let at_once = 2 * rayon::current_num_threads().max(1);
    let (send, receive) = std::sync::mpsc::sync_channel::<ItemOutcome>(at_once);
    std::thread::scope(|scope| {
        let writer = scope.spawn(move || -> Result<Written> {
            let mut out = Written::default();
            for item in receive {
                if let Outcome::Failed(why) = &item.outcome {
                    eprintln!("error: item {:?}: {why}", item.id);
                }
                out.add(staging, item)?;
            }
            Ok(out)
        });
        let computed = compute_items(job, consumer, frame, wanted, at_once, &send);
        drop(send);
        let written = writer
            .join()
            .unwrap_or_else(|_| Err(anyhow::anyhow!("the export's writer thread panicked")));
        // A writer error (a file that cannot be written) is the cause when both failed.
        let mut written = written?;
        written.filtered_out = computed?;
        Ok(written)
    })
}

/// Computes the wanted ok items' exports in batches of `at_once` and sends them in manifest
/// order while a reader thread streams the next rows from the shards (only the columns the
/// consumer reads; each finished shard's file hashed against its record as it is read);
/// stops early when the writer has stopped. Returns how many ok items `--where` left out.
fn compute_items(
    job: &Job,
    consumer: Consumer,
    frame: Frame,
    wanted: &Chosen,
    at_once: usize,
    send: &std::sync::mpsc::SyncSender<ItemOutcome>,
) -> Result<u64> {
    let (rows_in, rows_out) = std::sync::mpsc::sync_channel::<ShardRow>(at_once);
    std::thread::scope(|scope| {
        let reader = scope.spawn(move || read_wanted_rows(job, consumer, wanted, &rows_in));
        let names = ExportNames::for_job(job.file.items);
        let mut rows = rows_out.iter().peekable();
        'batches: while rows.peek().is_some() {
            let batch: Vec<ShardRow> = rows.by_ref().take(at_once).collect();
            let exports: Vec<ItemOutcome> = batch
                .par_iter()
                .map(|row| export_item(job, row, consumer, frame, &names))
                .collect();
            for item in exports {
                if send.send(item).is_err() {
                    break 'batches; // the writer stopped: its error is reported
                }
            }
        }
        // The reader stops at its next row once nobody receives them.
        drop(rows);
        drop(rows_out);
        reader
            .join()
            .unwrap_or_else(|_| Err(anyhow::anyhow!("the export's shard reader panicked")))
    })
}

/// Sends the wanted ok rows of the job's shards, in manifest order, until the receiver is
/// gone, and returns how many ok rows `--where` left out; a shard that cannot be read, or
/// whose file does not match its record, is an error.
fn read_wanted_rows(
    job: &Job,
    consumer: Consumer,
    chosen: &Chosen,
    send: &std::sync::mpsc::SyncSender<ShardRow>,
) -> Result<u64> {
    let wanted = chosen.ids;
    let mut shards = BTreeSet::new();
    for item in job.items() {
        let item = item?;
        if wanted.is_empty() || wanted.contains(item.record.id.as_str()) {
            shards.insert(item.shard);
        }
    }
    let columns = if consumer.reads_samples() {
        Columns::All
    } else {
        Columns::WithoutSamples
    };
    let mut receiver_gone = false;
    let mut filtered_out = 0;
    for shard in shards {
        for_each_shard_row(job, shard, Check::Full, columns, |mut row| {
            let mut keep =
                (wanted.is_empty() || wanted.contains(row.id.as_str())) && row.tensors.is_some();
            if let (true, Some(filter)) = (keep, chosen.filter) {
                let item = job.item(row.item_index)?;
                keep = filter.keeps(&mut row, item.as_ref())?;
                filtered_out += u64::from(!keep);
            }
            if keep && !receiver_gone {
                receiver_gone = send.send(row).is_err();
            }
            Ok(())
        })
        .with_context(|| format!("reading shard {shard}"))?;
        if receiver_gone {
            break;
        }
    }
    Ok(filtered_out)
}

/// One row's export, named and with its provenance: its files, or why it has none (a
/// consumer's own pipeline leaving it out is not a failure).
fn export_item(
    job: &Job,
    row: &ShardRow,
    consumer: Consumer,
    frame: Frame,
    names: &ExportNames,
) -> ItemOutcome {
    let stem = names.stem(row.item_index, &row.id);
    let outcome = match export_row(job, row, consumer, frame, &stem) {
        Ok(export) => Outcome::Files(export),
        Err(e) => match e.downcast_ref::<sparc3d_formats::Error>() {
            Some(sparc3d_formats::Error::LeftOut(why)) => Outcome::LeftOut(why.clone()),
            _ => Outcome::Failed(format!("{e:#}")),
        },
    };
    let provenance = job
        .item(row.item_index)
        .ok()
        .flatten()
        .map(|i| i.record.extra)
        .unwrap_or_default();
    ItemOutcome {
        id: row.id.clone(),
        stem,
        provenance,
        outcome,
    }
}

/// The files of one item.
fn export_row(
    job: &Job,
    row: &ShardRow,
    consumer: Consumer,
    frame: Frame,
    stem: &str,
) -> Result<sparc3d_formats::ItemExport> {
    let cubes = row.cubes()?;
    let stored = row.tensors.as_ref().and_then(|t| t.samples.as_ref());
    let samples = match stored.filter(|_| consumer.reads_samples()) {
        Some(t) => Some(t.to_samples()?),
        None => None,
    };
    let stored = row.tensors.as_ref().and_then(|t| t.attributes.as_ref());
    let attributes = match stored.filter(|_| consumer.reads_attributes()) {
        Some(t) => Some(t.to_attributes()?),
        None => None,
    };
    let stored_renders = row.tensors.as_ref().and_then(|t| t.renders.as_ref());
    let pngs: Vec<&[u8]> = stored_renders
        .map(|r| r.views.iter().map(|v| v.png.as_slice()).collect())
        .unwrap_or_default();
    let config = &job.file.config;
    // The manifest's sha256, else the one the row recorded of the bytes it converted; the id
    // where it covers the files the mesh names as well (colour variants of one mesh file).
    let frozen = job.item(row.item_index).ok().flatten();
    let source_sha256 = frozen
        .as_ref()
        .and_then(|i| i.record.sha256.as_deref())
        .or(row.source_sha256.as_deref());
    let source_key = match source_sha256 {
        Some(sha) if names_files_of(&row.id, sha) => Some(row.id.as_str()),
        other => other,
    };
    let item = Item {
        id: &row.id,
        item_index: row.item_index,
        stem,
        source_key,
        cubes: &cubes,
        samples: samples.as_ref().map(|s| StoredSamples {
            samples: s,
            params: &config.samples.params,
        }),
        attributes: attributes.as_ref(),
        renders: stored_renders.map(|r| sparc3d_formats::renders::StoredRenders {
            pngs: &pngs,
            transforms: &r.transforms,
        }),
        object_span: config.params.span(),
        output_span: config.params.output_span,
        frame,
    };
    Ok(consumer.files(&item)?)
}
