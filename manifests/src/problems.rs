//! Problems of one kind found while reading or freezing a manifest's rows: the first few kept
//! in full and all of them counted, so ten million bad rows cost a few lines of memory.

/// Problems of one kind: the first few in full, and how many.
#[derive(Debug, Default, Clone)]
pub struct Problems {
    listed: Vec<String>,
    count: u64,
}

impl Problems {
    /// Counts one more problem, keeping its text (made only then) while fewer than `keep` are.
    pub fn add(&mut self, what: impl FnOnce() -> String, keep: usize) {
        self.count += 1;
        if self.listed.len() < keep {
            self.listed.push(what());
        }
    }

    /// How many were counted.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The ones kept in full, in the order found.
    pub fn listed(&self) -> &[String] {
        &self.listed
    }

    /// The kept ones joined by `; `, and `; and N more` for the rest.
    pub fn listing(&self) -> String {
        let mut text = self.listed.join("; ");
        let more = self.count - self.listed.len() as u64;
        if more > 0 {
            text.push_str(&format!("; and {more} more"));
        }
        text
    }
}
