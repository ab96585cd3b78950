//! Requests to the bucket a few at a time: each of a list of keys through a blocking call,
//! at most a fixed number in flight, so that a command over thousands of objects waits for
//! round trips in parallel without opening thousands of connections.

use anyhow::{anyhow, Result};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// How many requests a command keeps in flight when it reads or writes many small objects.
pub const IN_FLIGHT: usize = 16;

/// `call` on each of `items`, at most `in_flight` at once (threads taking the next item as
/// they finish one); the results in the order of `items`, or the first error in that order
/// (after an error no new item is started).
pub fn each<T: Sync, R: Send>(
    items: &[T],
    in_flight: usize,
    call: impl Fn(&T) -> Result<R> + Sync,
) -> Result<Vec<R>> {
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let worker = || {
        let mut done = Vec::new();
        while !failed.load(Ordering::Relaxed) {
            let at = next.fetch_add(1, Ordering::Relaxed);
            let Some(item) = items.get(at) else {
                break;
            };
            let result = call(item);
            if result.is_err() {
                failed.store(true, Ordering::Relaxed);
            }
            done.push((at, result));
        }
        done
    };
    let threads = in_flight.clamp(1, items.len().max(1));
    let mut results: Vec<(usize, Result<R>)> = std::thread::scope(|scope| {
        let running: Vec<_> = (0..threads).map(|_| scope.spawn(worker)).collect();
        running
            .into_iter()
            .flat_map(|t| {
                t.join()
                    .unwrap_or_else(|_| vec![(usize::MAX, Err(anyhow!("a request stopped")))])
            })
            .collect()
    });
    results.sort_by_key(|(at, _)| *at);
    let mut out = Vec::with_capacity(items.len());
    for (_, result) in results {
        out.push(result?);
    }
    if out.len() < items.len() {
        return Err(anyhow!(
            "{} requests were not made",
            items.len() - out.len()
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_keep_the_order_of_the_items_and_the_first_error_is_said() -> Result<()> {
        let items: Vec<u64> = (0..100).collect();
        assert_eq!(
            each(&items, 7, |i| Ok(i * 2))?,
            (0..100).map(|i| i * 2).collect::<Vec<_>>()
        );
        assert!(each(&Vec::<u64>::new(), 4, |i| Ok(*i))?.is_empty());
        let err = each(&items, 3, |i| match i {
            40 | 70 => Err(anyhow!("item {i} failed")),
            _ => Ok(*i),
        });
        assert_eq!(
            err.err().map(|e| e.to_string()),
            Some("item 40 failed".into())
        );
        Ok(())
    }
}
