"""`StreamingDataset.loader(...)`: a torch DataLoader that tells its `StreamingDataset` how
many items each worker's batches carried to the training loop, so that `state_dict()` is exact
with workers (they read ahead: what a worker has yielded is not what the loop has received).

Each batch is tagged in its worker by the collate function (`Tagged`) with the worker's id and
its number of items, and the tag is taken off in the main process as the batch is handed over.
"""

from __future__ import annotations

from typing import Any, Callable, Optional


class Tagged:
    """A collate function that returns `(collate(batch), (worker id, items in batch))`."""

    def __init__(self, collate: Callable, batched: bool):
        self.collate, self.batched = collate, batched

    def __call__(self, batch: Any):
        from torch.utils.data import get_worker_info

        info = get_worker_info()
        n = len(batch) if self.batched else 1
        return self.collate(batch), (0 if info is None else info.id, n)


_loader_class = None


def streaming_loader(dataset, batch_size: Optional[int] = 1, collate_fn: Optional[Callable] = None,
                     **kwargs):
    """A DataLoader over `dataset` (a StreamingDataset) with DataLoader's own arguments; each
    batch it yields is what `collate_fn` made (torch's default without one). Workers are
    started for each epoch (`persistent_workers` is refused: a worker kept from the last epoch
    would not see `set_epoch`)."""
    import torch.utils.data as tud

    global _loader_class
    if kwargs.get("persistent_workers"):
        raise ValueError("persistent_workers=True: workers kept across epochs keep the epoch "
                         "they were started in; StreamingDataset needs them started per epoch")
    if _loader_class is None:
        _loader_class = type("StreamingLoader", (_LoaderMixin, tud.DataLoader), {
            "__doc__": _LoaderMixin.__doc__, "__module__": __name__})
    if collate_fn is None:
        collate_fn = tud.default_collate if batch_size is not None else tud.default_convert
    tagged = Tagged(collate_fn, batch_size is not None)
    return _loader_class(dataset, batch_size=batch_size, collate_fn=tagged, **kwargs)


class _LoaderMixin:
    """A DataLoader over a StreamingDataset that reports each batch's worker to it."""

    def __iter__(self):
        """The batches, each counted for its worker as the loop takes it."""
        ds, workers = self.dataset, max(self.num_workers, 1)
        ds._begin(workers)
        ds._tracked = True
        it = super().__iter__()
        if self.num_workers > 0:
            # The workers have their copies of the dataset, with the position to start at.
            ds._iter_skip, ds._tracked = None, False
        for batch, (worker, n) in it:
            if self.num_workers > 0:
                ds._received(worker, n)
            yield batch

    def __len__(self) -> int:
        """Batches of the epoch from its start or a loaded position: each worker's items in
        batches of their own."""
        workers = max(self.num_workers, 1)
        start = self.dataset.start_position(workers)
        left = [n - s for n, s in zip(self.dataset.worker_sizes(workers), start)]
        if self.batch_size is None:
            return sum(left)
        per = (lambda n: n // self.batch_size) if self.drop_last else (
            lambda n: -(-n // self.batch_size))
        return sum(per(n) for n in left)
