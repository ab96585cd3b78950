//! `sparc3d report JOB -o report.html`: one self-contained static page about a job — status,
//! histograms of active vertices, output faces, time and stored bytes per item, the
//! validation results when `sparc3d validate` has run, previews of a sample of `ok` items and
//! the failures table.
//!
//! Everything is inline: CSS, histograms as SVG, previews as PNG `data:` URIs; no JavaScript.
//! Every `<img>` carries `onload`/`onerror` attributes marking it `data-loaded` or
//! `data-broken`, so a headless browser's dump of the page shows whether each picture decoded.

use crate::check::pictures::preview_row;
use crate::rows::item_lookup;
use crate::rows::summary::{summarize, JobSummary};
use crate::util::units::format_seconds;
use anyhow::{Context, Result};
use base64::Engine;
use sparc3d_render::cond::thumbnail::thumbnail;
use sparc3d_render::CompareOptions;
use sparc3d_schema::{ItemStatus, ShardRow};
use sparc3d_workers::store::read::shard_rows;
use sparc3d_workers::Job;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    /// Output page (HTML).
    #[arg(short, long)]
    pub output: PathBuf,
    /// `ok` items to preview, evenly spaced in manifest order.
    #[arg(long, default_value_t = 8)]
    pub previews: usize,
    /// Views per preview.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub views: u32,
    /// Side of one preview view in pixels.
    #[arg(long, default_value_t = 160, value_parser = clap::value_parser!(u32).range(16..=1024))]
    pub tile: u32,
    /// Failed items listed at most.
    #[arg(long, default_value_t = 1000)]
    pub max_failures: usize,
}

/// Per-item numbers read from the rows.
#[derive(Debug, Default)]
struct Columns {
    /// Active vertices of `ok` items.
    active_vertices: Vec<f64>,
    /// Output faces of `ok` items that were extracted.
    output_faces: Vec<f64>,
    /// Seconds per finished item (ok or failed).
    total_seconds: Vec<f64>,
    /// Stored tensor bytes per `ok` item.
    stored_bytes: Vec<f64>,
    /// Ids of `ok` items, in manifest order.
    ok_ids: Vec<String>,
    /// Failed items: (id, uri, class, first line of the message, provenance as
    /// `name=value; …`).
    failures: Vec<[String; 5]>,
    /// Finished items per value of each provenance column: (ok, failed).
    provenance: BTreeMap<String, BTreeMap<String, (u64, u64)>>,
    /// Failed items not listed (beyond `max_failures`).
    failures_left_out: usize,
}

/// Runs `sparc3d report`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    // Messages name the job as given (a URL), not its local view.
    let named = args.job.clone();
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    let job = crate::job::setup::open_read_only(&args.job)?;
    let summary = summarize(&job)?;
    let columns = read_columns(&job, args.max_failures)?;
    let options = CompareOptions {
        views: args.views,
        tile: args.tile,
        elevation_deg: 30.0,
    };
    let previews: Vec<Preview> = evenly_spaced(&columns.ok_ids, args.previews)
        .into_iter()
        .map(|id| preview(&job, id, &options))
        .collect();
    let html = page(&job, &summary, &columns, &previews);
    std::fs::write(&args.output, html)
        .with_context(|| format!("writing {}", args.output.display()))?;
    eprintln!(
        "report of {} ({} ok, {} failed, {} previews) written to {}",
        named.display(),
        summary.ok,
        summary.failed,
        previews.len(),
        args.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Reads every finished row of the job (shards done or in progress).
fn read_columns(job: &Job, max_failures: usize) -> Result<Columns> {
    let mut c = Columns::default();
    for shard in 0..job.file.shards {
        let mut rows = shard_rows(job, shard, sparc3d_workers::store::state::Check::Quick)?;
        rows.sort_by_key(|r| r.item_index);
        for row in rows {
            let extra = job
                .item(row.item_index)?
                .map(|i| i.record.extra)
                .unwrap_or_default();
            add_provenance(&mut c, &extra, row.status);
            add_row(&mut c, row, &extra, max_failures);
        }
    }
    Ok(c)
}

/// Counts a finished item under each of its provenance values.
fn add_provenance(c: &mut Columns, extra: &BTreeMap<String, String>, status: ItemStatus) {
    for (name, value) in extra {
        let counts = c.provenance.entry(name.clone()).or_default();
        let (ok, failed) = counts.entry(value.clone()).or_default();
        match status {
            ItemStatus::Ok => *ok += 1,
            ItemStatus::Failed => *failed += 1,
            ItemStatus::Skipped => {}
        }
    }
}

fn add_row(c: &mut Columns, row: ShardRow, extra: &BTreeMap<String, String>, max_failures: usize) {
    if row.timings.total_s > 0.0 {
        c.total_seconds.push(row.timings.total_s);
    }
    if row.status == ItemStatus::Ok {
        if let Some(counts) = &row.counts {
            c.active_vertices.push(counts.active_vertices as f64);
            if let Some(f) = counts.output_faces {
                c.output_faces.push(f as f64);
            }
        }
        if let Some(t) = &row.tensors {
            let bytes: usize = t
                .iter()
                .iter()
                .filter_map(|(_, e)| *e)
                .map(|e| e.blob.len())
                .sum();
            c.stored_bytes.push(bytes as f64);
        }
        c.ok_ids.push(row.id);
    } else if row.status == ItemStatus::Failed {
        if c.failures.len() >= max_failures {
            c.failures_left_out += 1;
            return;
        }
        let class = row.error_class.map(|e| e.as_str()).unwrap_or("unknown");
        let message = row.error_message.unwrap_or_default();
        let first = message.lines().next().unwrap_or("").to_string();
        let provenance: Vec<String> = extra.iter().map(|(k, v)| format!("{k}={v}")).collect();
        c.failures.push([
            row.id,
            row.uri,
            class.to_string(),
            first,
            provenance.join("; "),
        ]);
    }
}

/// `k` items evenly spaced over `ids` (all of them when there are fewer), deterministic.
fn evenly_spaced(ids: &[String], k: usize) -> Vec<&str> {
    let n = ids.len();
    if k == 0 || n == 0 {
        return Vec::new();
    }
    if k >= n {
        return ids.iter().map(String::as_str).collect();
    }
    (0..k).map(|i| ids[i * n / k].as_str()).collect()
}

/// One rendered preview, or why it could not be made.
struct Preview {
    id: String,
    uri: String,
    png: Result<Vec<u8>>,
    /// Thumbnails of the item's condition views (a job with `[renders]`), and its seconds a
    /// view (the mean).
    views: Vec<std::result::Result<Vec<u8>, String>>,
    view_seconds: f64,
}

/// Side of a condition view's thumbnail in the contact sheet, in pixels.
const THUMBNAIL: u32 = 128;

fn preview(job: &Job, id: &str, options: &CompareOptions) -> Preview {
    let row = item_lookup::find(job, id).and_then(|item| item_lookup::row(job, &item));
    let uri = row.as_ref().map(|r| r.uri.clone()).unwrap_or_default();
    let renders = row
        .as_ref()
        .ok()
        .and_then(|r| r.tensors.as_ref())
        .and_then(|t| t.renders.as_ref());
    let views = renders.map_or_else(Vec::new, |r| {
        let thumb = |v: &sparc3d_schema::RenderedView| thumbnail(&v.png, THUMBNAIL);
        r.views.iter().map(thumb).collect()
    });
    let view_seconds = renders.map_or(0.0, |r| {
        r.views.iter().map(|v| v.seconds).sum::<f64>() / r.views.len().max(1) as f64
    });
    let png = row
        .and_then(|r| preview_row(&r, options, true))
        .and_then(|image| image.encode_png().context("encoding PNG"));
    Preview {
        id: id.to_string(),
        uri,
        png,
        views,
        view_seconds,
    }
}

/// Escapes text for HTML content and attribute values.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(ch),
        }
    }
    out
}

const CSS: &str =
    "body{font:14px/1.4 system-ui,sans-serif;margin:24px;color:#222;max-width:1400px}\
h1{font-size:22px}h2{font-size:18px;margin-top:28px;border-bottom:1px solid #ddd}\
table{border-collapse:collapse}td,th{border:1px solid #ddd;padding:3px 8px;text-align:left;\
vertical-align:top}th{background:#f4f4f4}td.n{text-align:right}\
.hists{display:flex;flex-wrap:wrap;gap:16px}.previews{display:flex;flex-wrap:wrap;gap:16px}\
figure{margin:0}figcaption{font-size:12px;color:#555;max-width:520px;word-break:break-all}\
pre{background:#f7f7f7;padding:8px;overflow-x:auto}.err{color:#b00}";

/// Marks a picture that loaded, for headless checks of the page.
const ONLOAD: &str = "this.setAttribute('data-loaded','1')";
/// Marks a picture that failed to load, for headless checks of the page.
const ONERROR: &str = "this.setAttribute('data-broken','1')";

fn page(job: &Job, s: &JobSummary, c: &Columns, previews: &[Preview]) -> String {
    let root = job.layout.root.display().to_string();
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>sparc3d report: {t}</title><style>{CSS}</style></head><body>\n\
         <h1>sparc3d report: {t}</h1>\n",
        t = esc(&root)
    );
    status_section(&mut h, job, s);
    h.push_str("<h2>Distributions</h2>\n<div class=\"hists\">\n");
    h.push_str(&histogram_svg(
        "active vertices per ok item",
        &c.active_vertices,
        "",
    ));
    h.push_str(&histogram_svg(
        "output faces per ok item",
        &c.output_faces,
        "",
    ));
    h.push_str(&histogram_svg("seconds per item", &c.total_seconds, "s"));
    h.push_str(&histogram_svg(
        "stored tensor bytes per ok item",
        &c.stored_bytes,
        "B",
    ));
    h.push_str("</div>\n");
    validation_section(&mut h, &job.layout.root);
    previews_section(&mut h, previews, job.file.config.attributes.enabled);
    if job.file.config.renders.enabled {
        contact_sheet(&mut h, previews);
    }
    provenance_section(&mut h, c);
    failures_section(&mut h, c);
    h.push_str("</body></html>\n");
    h
}

fn status_section(h: &mut String, job: &Job, s: &JobSummary) {
    let p = &job.file.config.params;
    h.push_str("<h2>Status</h2>\n<table>\n");
    let rows: Vec<(&str, String)> = vec![
        ("resolution", p.resolution.to_string()),
        (
            "shards",
            format!(
                "{} done, {} running, {} pending (of {})",
                s.shards_done, s.shards_running, s.shards_pending, s.shards
            ),
        ),
        (
            "items",
            format!(
                "{} ok, {} failed, {} pending (of {})",
                s.ok, s.failed, s.pending, s.items
            ),
        ),
        (
            "rate",
            s.items_per_hour
                .map(|r| format!("{r:.0} items/hour"))
                .unwrap_or_else(|| "—".into()),
        ),
        (
            "ETA",
            match s.eta_seconds {
                Some(e) if s.pending > 0 => format_seconds(e),
                _ => "—".into(),
            },
        ),
        ("item time (sum)", format_seconds(s.item_seconds)),
    ];
    for (k, v) in rows {
        let _ = writeln!(h, "<tr><th>{}</th><td>{}</td></tr>", esc(k), esc(&v));
    }
    h.push_str("</table>\n");
    if !s.error_classes.is_empty() {
        let mut classes: Vec<_> = s.error_classes.iter().collect();
        classes.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        h.push_str("<h3>Error classes</h3>\n<table><tr><th>class</th><th>items</th></tr>\n");
        for (class, n) in classes {
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td class=\"n\">{n}</td></tr>",
                esc(class)
            );
        }
        h.push_str("</table>\n");
    }
}

/// `JOB/validation/summary.md` verbatim and the number of records in `report.jsonl`.
fn validation_section(h: &mut String, root: &Path) {
    let dir = root.join("validation");
    h.push_str("<h2>Validation</h2>\n");
    let summary = std::fs::read_to_string(dir.join("summary.md"));
    let records = std::fs::read_to_string(dir.join("report.jsonl"))
        .map(|s| s.lines().filter(|l| !l.trim().is_empty()).count());
    if summary.is_err() && records.is_err() {
        h.push_str("<p>No validation results (run <code>sparc3d validate JOB</code>).</p>\n");
        return;
    }
    if let Ok(n) = records {
        let _ = writeln!(
            h,
            "<p>{n} per-item records in <code>validation/report.jsonl</code>.</p>"
        );
    }
    if let Ok(md) = summary {
        let _ = writeln!(h, "<pre>{}</pre>", esc(&md));
    }
}

fn previews_section(h: &mut String, previews: &[Preview], coloured: bool) {
    h.push_str(
        "<h2>Previews</h2>\n<p>Source above, output below, same cameras. Back faces are red: \
         red on top is an open source, red below a broken output.",
    );
    if coloured {
        h.push_str(
            " The job stores attributes: the source is drawn in its own colours (materials, \
             textures, vertex colours), the output with each vertex in its cell's base colour.",
        );
    }
    h.push_str("</p>\n<div class=\"previews\">\n");
    if previews.is_empty() {
        h.push_str("<p>No ok items to preview.</p>\n");
    }
    let b64 = base64::engine::general_purpose::STANDARD;
    for p in previews {
        let caption = format!("{} — {}", p.id, p.uri);
        match &p.png {
            Ok(bytes) => {
                let _ = writeln!(
                    h,
                    "<figure><img src=\"data:image/png;base64,{}\" alt=\"{a}\" \
                     onload=\"{ONLOAD}\" onerror=\"{ONERROR}\"><figcaption>{a}</figcaption></figure>",
                    b64.encode(bytes),
                    a = esc(&caption)
                );
            }
            Err(e) => {
                let _ = writeln!(
                    h,
                    "<figure><p class=\"err\">no preview: {}</p><figcaption>{}</figcaption>\
                     </figure>",
                    esc(&format!("{e:#}")),
                    esc(&caption)
                );
            }
        }
    }
    h.push_str("</div>\n");
}

/// The condition views of the previewed items, each row one item's views on white
/// (docs/RENDERS.md), with its seconds a view.
fn contact_sheet(h: &mut String, previews: &[Preview]) {
    h.push_str(
        "<h2>Condition views</h2>\n<p>The views each previewed item's row stores, in order, \
         composited on white as the loaders show them.</p>\n",
    );
    let b64 = base64::engine::general_purpose::STANDARD;
    for p in previews {
        let _ = write!(h, "<div class=\"previews\">");
        for (i, v) in p.views.iter().enumerate() {
            let alt = esc(&format!("{} view {i:03}", p.id));
            let _ = match v {
                Ok(png) => write!(
                    h,
                    "<img class=\"view\" src=\"data:image/png;base64,{}\" alt=\"{alt}\" \
                     onload=\"{ONLOAD}\" onerror=\"{ONERROR}\">",
                    b64.encode(png)
                ),
                Err(e) => write!(h, "<p class=\"err\">{alt}: {}</p>", esc(e)),
            };
        }
        let caption = match p.views.len() {
            0 => "no views stored".to_string(),
            n => format!("{n} views, {:.3} s a view", p.view_seconds),
        };
        let _ = writeln!(
            h,
            "</div><p>{} — {}</p>",
            esc(&format!("{} — {}", p.id, p.uri)),
            esc(&caption)
        );
    }
}

/// Values of a provenance column listed in the report; the rest are counted.
const PROVENANCE_VALUES: usize = 10;

/// Each provenance column: its most frequent values with the ok and failed items of each.
fn provenance_section(h: &mut String, c: &Columns) {
    if c.provenance.is_empty() {
        return;
    }
    h.push_str("<h2>Provenance</h2>\n");
    for (name, values) in &c.provenance {
        let mut v: Vec<(&String, &(u64, u64))> = values.iter().collect();
        v.sort_by(|a, b| (b.1 .0 + b.1 .1).cmp(&(a.1 .0 + a.1 .1)).then(a.0.cmp(b.0)));
        let _ = writeln!(
            h,
            "<h3>manifest.{}</h3>\n<table><tr><th>value</th><th>ok</th><th>failed</th></tr>",
            esc(name)
        );
        for (value, (ok, failed)) in v.iter().take(PROVENANCE_VALUES) {
            let shown = if value.is_empty() { "(none)" } else { value };
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{ok}</td><td>{failed}</td></tr>",
                esc(shown)
            );
        }
        h.push_str("</table>\n");
        if v.len() > PROVENANCE_VALUES {
            let _ = writeln!(h, "<p>{} more values.</p>", v.len() - PROVENANCE_VALUES);
        }
    }
}

fn failures_section(h: &mut String, c: &Columns) {
    let total = c.failures.len() + c.failures_left_out;
    let _ = writeln!(h, "<h2>Failures ({total})</h2>");
    if total == 0 {
        h.push_str("<p>No failed items.</p>\n");
        return;
    }
    let with_provenance = !c.provenance.is_empty();
    h.push_str("<table><tr><th>id</th><th>uri</th><th>class</th><th>message</th>");
    h.push_str(if with_provenance {
        "<th>manifest</th></tr>\n"
    } else {
        "</tr>\n"
    });
    for f in &c.failures {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
            esc(&f[0]),
            esc(&f[1]),
            esc(&f[2]),
            esc(&f[3])
        );
        if with_provenance {
            let _ = write!(h, "<td>{}</td>", esc(&f[4]));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    if c.failures_left_out > 0 {
        let _ = writeln!(
            h,
            "<p>{} more not listed (see <code>sparc3d failures JOB</code>).</p>",
            c.failures_left_out
        );
    }
}

/// Short human form of a number: 950, 12.3k, 4.5M, 1.2G.
fn short(v: f64) -> String {
    let a = v.abs();
    if a >= 1e9 {
        format!("{:.1}G", v / 1e9)
    } else if a >= 1e6 {
        format!("{:.1}M", v / 1e6)
    } else if a >= 1e4 {
        format!("{:.0}k", v / 1e3)
    } else if a >= 1e3 {
        format!("{:.1}k", v / 1e3)
    } else if a >= 10.0 || a == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

/// A histogram as inline SVG: 20 bins, logarithmic when the values span more than two
/// decades, with the count, min, median and max in the title.
fn histogram_svg(title: &str, values: &[f64], unit: &str) -> String {
    const W: f64 = 400.0;
    const H: f64 = 200.0;
    const BINS: usize = 20;
    let (left, right, top, bottom) = (36.0, 10.0, 30.0, 34.0);
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let mut s = String::new();
    let _ = write!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" \
         viewBox=\"0 0 {W} {H}\" role=\"img\" aria-label=\"{t}\">\
         <rect width=\"{W}\" height=\"{H}\" fill=\"#fafafa\" stroke=\"#ddd\"/>",
        t = esc(title)
    );
    let header = if v.is_empty() {
        format!("{title}: no data")
    } else {
        format!(
            "{title} (n={}, median {}{unit})",
            v.len(),
            short(v[v.len() / 2])
        )
    };
    let _ = write!(
        s,
        "<text x=\"8\" y=\"18\" font-size=\"13\" font-family=\"sans-serif\">{}</text>",
        esc(&header)
    );
    if let (Some(&lo), Some(&hi)) = (v.first(), v.last()) {
        let log = lo > 0.0 && hi / lo > 100.0;
        let map = |x: f64| if log { x.log10() } else { x };
        let (a, b) = (map(lo), map(hi));
        let span = if b > a { b - a } else { 1.0 };
        let mut counts = [0usize; BINS];
        for &x in &v {
            let i = (((map(x) - a) / span) * BINS as f64) as usize;
            counts[i.min(BINS - 1)] += 1;
        }
        let max = counts.iter().copied().max().unwrap_or(1).max(1) as f64;
        let plot_w = W - left - right;
        let plot_h = H - top - bottom;
        let bw = plot_w / BINS as f64;
        for (i, &n) in counts.iter().enumerate() {
            if n == 0 {
                continue;
            }
            let bh = n as f64 / max * plot_h;
            let _ = write!(
                s,
                "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"#5b7fbf\">\
                 <title>{n}</title></rect>",
                left + i as f64 * bw + 1.0,
                top + plot_h - bh,
                (bw - 2.0).max(1.0),
                bh
            );
        }
        let axis_y = top + plot_h;
        let _ = write!(
            s,
            "<line x1=\"{left}\" y1=\"{axis_y}\" x2=\"{}\" y2=\"{axis_y}\" stroke=\"#888\"/>\
             <text x=\"{left}\" y=\"{}\" font-size=\"11\" font-family=\"sans-serif\">{}</text>\
             <text x=\"{}\" y=\"{}\" font-size=\"11\" font-family=\"sans-serif\" \
             text-anchor=\"end\">{}</text>\
             <text x=\"{}\" y=\"{}\" font-size=\"11\" font-family=\"sans-serif\" \
             text-anchor=\"middle\" fill=\"#666\">{}</text>\
             <text x=\"4\" y=\"{}\" font-size=\"11\" font-family=\"sans-serif\">{}</text>",
            W - right,
            axis_y + 14.0,
            esc(&format!("{}{unit}", short(lo))),
            W - right,
            axis_y + 14.0,
            esc(&format!("{}{unit}", short(hi))),
            left + plot_w / 2.0,
            axis_y + 28.0,
            if log { "log scale" } else { "linear scale" },
            top + 10.0,
            max as usize
        );
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_html() {
        assert_eq!(
            esc("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
    }

    #[test]
    fn evenly_spaced_is_deterministic_and_bounded() {
        let ids: Vec<String> = (0..10).map(|i| i.to_string()).collect();
        assert_eq!(evenly_spaced(&ids, 3), vec!["0", "3", "6"]);
        assert_eq!(evenly_spaced(&ids, 20).len(), 10);
        assert!(evenly_spaced(&ids, 0).is_empty());
    }

    #[test]
    fn histogram_counts_every_value() {
        let v: Vec<f64> = (1..=1000).map(|i| i as f64).collect();
        let svg = histogram_svg("x", &v, "");
        assert!(svg.contains("n=1000"));
        assert!(svg.contains("log scale"));
        let total: usize = svg
            .split("<title>")
            .skip(1)
            .filter_map(|p| p.split('<').next()?.parse::<usize>().ok())
            .sum();
        assert_eq!(total, 1000);
        assert!(histogram_svg("empty", &[], "").contains("no data"));
    }
}
