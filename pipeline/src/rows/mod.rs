//! A job's rows read back: filters, item lookup, samples, summaries, near-duplicates, export names.

pub mod export_name;
pub mod item_lookup;
pub mod near_duplicates;
pub mod row_filter;
pub mod sample;
pub mod summary;
