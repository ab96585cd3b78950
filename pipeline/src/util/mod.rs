//! Helpers every command shares: units, the allocator, hints, the machine, memory, statistics, error lines.

pub mod error_line;
pub mod hints;
pub mod huge_pages;
pub mod machine;
pub mod memory;
pub mod stats;
pub mod units;
