//! Stage 6, the inside test: what reachability alone cannot tell, decided by the source's
//! generalised winding number |w| ([`crate::queries::winding`]), on by default
//! (`Params::inside_test`).
//!
//! The flood ([`crate::stages::flood`]) reaches every surface-free cell joined to the grid's
//! border; the rest form *enclosed regions*: connected sets (through cell faces) of
//! surface-free cells the flood cannot reach. Reachability alone would call them all solid, but
//! whether a region is material or air is a property of the source: the inside of a cube's
//! cavity, or the space between a double-walled hull and the parts it holds, is enclosed and
//! empty. So every region is decided by |w| sampled at a few of its cells ([`vote`]): solid,
//! air, or ambiguous (an inconsistently oriented soup, overlapping open sheets), which keeps
//! what reachability says: solid. |w| rather than w, so a mesh oriented inwards throughout
//! reads as it does outwards. Air regions are then treated as outside
//! ([`regions::mark_air`]), so a surface between the outside (or air) and a solid region keeps
//! its exact position, and the parts inside a hollow hull come out as closed surfaces of their
//! own.
//!
//! - [`vote`] — the median |w| at a few points and its verdict (also the sealing's, stage 4).
//! - [`classify`] — the enclosed regions found brick by brick and decided, before the signs.
//! - [`regions`] — which region a cell or vertex lies in; air handed to the flood's outside.
//! - [`sealed`] — vertices sealed in by triangles on every side, decided in groups, and the
//!   thin closed parts they form; [`gaps`] — those parts the grid cannot hold.
//! - [`nesting`] — solids wholly nested in solids, whose surfaces the sign stage drops.
//!
//! The regions are decided before the sign stage (7), the sealed vertices and the nesting
//! between its two halves, once every other vertex has its side.

pub mod classify;
pub mod gaps;
pub mod nesting;
pub mod regions;
pub mod sealed;
pub mod vote;

/// Longest piece, in voxels, the winding tree cuts triangles into ([`crate::queries::winding`]): 32
/// voxels, or 1/32 of the grid at resolutions above 1024, so the number of pieces does not
/// grow with the resolution. 8 voxels gave the same outputs on the dev corpus at 256³ but
/// up to 50 times as many pieces as triangles (large flat faces), and cutting, sorting and
/// summing them was most of the inside test's time on such meshes; 16, 32 and 64 gave the
/// same bytes and about half the time of 8 (docs/QUALITY.md, issue 15).
pub fn winding_piece(n: u32) -> f64 {
    (n as f64 / 32.0).max(32.0)
}
