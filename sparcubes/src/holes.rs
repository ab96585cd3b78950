//! Hole filling (paper §3.4): boundary half-edges → closed loops → ear filling by smallest angle.
