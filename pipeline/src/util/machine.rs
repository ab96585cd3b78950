//! What this machine offers a run (cores, the threads the environment asks for, memory not in
//! use) and the workers and threads per conversion `run` picks from them when not told.

/// This process's cores (its CPU affinity, as the standard library reads it); 1 if unknown.
pub fn cores() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

/// `RAYON_NUM_THREADS` when set to a positive number.
pub fn threads_from_env() -> Option<usize> {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0)
}

/// `RAYON_NUM_THREADS` when set, else the cores.
pub fn threads_from_env_or_cores() -> usize {
    threads_from_env().unwrap_or_else(cores)
}

/// Memory available to new processes (`MemAvailable` of /proc/meminfo), in bytes.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// The workers (items converted at once) and threads per conversion of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunPlan {
    /// Items converted at once, over all shards.
    pub workers: usize,
    /// Threads per conversion (0: `RAYON_NUM_THREADS` decides).
    pub threads: usize,
    /// How they were picked, for the run's first line.
    pub why: String,
}

/// What a run has to do and where: `items` left to convert, on `cores` cores with `memory`
/// bytes available, items limited to `item_memory` bytes each (0: no limit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Machine {
    /// Items left to convert.
    pub items: u64,
    /// Cores of this process.
    pub cores: usize,
    /// Memory available, when known.
    pub memory: Option<u64>,
    /// The item memory limit (0: none).
    pub item_memory: u64,
}

/// The plan for `--workers requested` (or `auto`: `None`) on `m`: as many workers as cores,
/// but no more than the memory holds at the item limit each, and the cores divided among them
/// as threads. `env_threads` (`RAYON_NUM_THREADS`) wins for the threads. A number asked for
/// is taken up to what can run at once: the items left and what the memory holds (issue 64
/// item 5: `--workers 10000` on a 10-item job started thousands of lanes and stalled), and
/// the plan says what it took.
pub fn plan(requested: Option<usize>, m: Machine, env_threads: Option<usize>) -> RunPlan {
    let cores = m.cores.max(1);
    let fits = match (m.memory, m.item_memory) {
        (Some(mem), l) if l > 0 => Some(((mem / l) as usize).max(1)),
        _ => None,
    };
    let (workers, mut why) = match (requested, fits) {
        (Some(n), _) => asked(n, m, fits),
        (None, Some(f)) if f < cores => (
            f,
            format!(
                "{f} workers (auto: {cores} cores, but memory for {f} items at the {} item limit)",
                crate::util::units::format_size(m.item_memory)
            ),
        ),
        (None, _) => (cores, format!("{cores} workers (auto: {cores} cores)")),
    };
    let threads = match env_threads {
        Some(_) => {
            why.push_str(", threads per conversion from RAYON_NUM_THREADS");
            0
        }
        None => {
            let t = (cores / workers).max(1);
            why.push_str(&format!(", {t} thread{} per conversion", plural(t)));
            t
        }
    };
    RunPlan {
        workers,
        threads,
        why,
    }
}

/// `n` workers asked for, taken up to the items left (`m.items`) and what the memory holds
/// (`fits`), with what was taken and why.
fn asked(n: usize, m: Machine, fits: Option<usize>) -> (usize, String) {
    let n = n.max(1);
    let items = usize::try_from(m.items).unwrap_or(usize::MAX).max(1);
    let mut taken = n;
    let mut reasons: Vec<String> = Vec::new();
    if items < taken {
        taken = items;
        reasons.push(format!("{items} item{} left", plural(items)));
    }
    if let Some(f) = fits.filter(|&f| f < taken) {
        taken = f;
        reasons.push(format!(
            "memory for {f} item{} at the {} item limit",
            plural(f),
            crate::util::units::format_size(m.item_memory)
        ));
    }
    match reasons.is_empty() {
        true => (n, format!("{n} workers")),
        false => (
            taken,
            format!("{taken} workers ({n} asked: {})", reasons.join(", ")),
        ),
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: u64 = 1 << 30;

    /// `plan` on a machine of `cores` cores with `memory` and an item limit, many items left.
    fn plan(
        requested: Option<usize>,
        cores: usize,
        memory: Option<u64>,
        item_memory: u64,
        env_threads: Option<usize>,
    ) -> RunPlan {
        let m = Machine {
            items: 1 << 40,
            cores,
            memory,
            item_memory,
        };
        super::plan(requested, m, env_threads)
    }

    #[test]
    fn auto_takes_every_core_while_memory_allows() {
        let p = plan(None, 16, Some(128 * G), 8 * G, None);
        assert_eq!((p.workers, p.threads), (16, 1));
        assert_eq!(
            p.why,
            "16 workers (auto: 16 cores), 1 thread per conversion"
        );
        let p = plan(None, 16, Some(40 * G), 8 * G, None);
        assert_eq!((p.workers, p.threads), (5, 3));
        assert!(p
            .why
            .starts_with("5 workers (auto: 16 cores, but memory for 5 items"));
        // Too little memory for one item still runs one; no limit, no memory bound.
        assert_eq!(plan(None, 4, Some(G), 8 * G, None).workers, 1);
        assert_eq!(plan(None, 4, Some(G), 0, None).workers, 4);
    }

    #[test]
    fn asked_workers_and_the_environments_threads_win() {
        let p = plan(Some(3), 8, None, 8 * G, None);
        assert_eq!((p.workers, p.threads), (3, 2));
        let p = plan(Some(0), 8, None, 0, Some(4));
        assert_eq!((p.workers, p.threads), (1, 0));
        assert!(p.why.ends_with("from RAYON_NUM_THREADS"), "{}", p.why);
    }

    #[test]
    fn workers_asked_past_the_items_or_the_memory_are_taken_as_many_as_run() {
        let m = Machine {
            items: 10,
            cores: 2,
            memory: Some(64 * G),
            item_memory: 8 * G,
        };
        let p = super::plan(Some(10_000), m, None);
        assert_eq!((p.workers, p.threads), (8, 1));
        assert_eq!(
            p.why,
            "8 workers (10000 asked: 10 items left, memory for 8 items at the 8G item limit), \
             1 thread per conversion"
        );
        let p = super::plan(Some(1000), Machine { memory: None, ..m }, None);
        assert!(
            p.why.starts_with("10 workers (1000 asked: 10 items left)"),
            "{}",
            p.why
        );
        // What can run is taken as asked.
        assert_eq!(
            super::plan(Some(4), m, None).why,
            "4 workers, 1 thread per conversion"
        );
    }
}
