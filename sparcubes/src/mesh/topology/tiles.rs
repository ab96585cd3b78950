//! The links of the vertices one tile at a time: the fast path of [`super::check`] for
//! meshes whose triangles come in nearly the order of their vertices, as every output of
//! [`crate::extract`] does (cells in grid order, crossing points numbered by grid edge, so a
//! run of triangles uses a few narrow runs of vertex numbers).
//!
//! The vertices are cut into tiles of [`TILE`]. The pass over the triangles in
//! [`super::check`] notes which tiles each chunk of triangles uses ([`TileSet`]); each tile
//! then reads only those chunks, keeps the links of its own vertices in rows small enough to
//! stay in cache while it fills them, and checks them. A tile belongs to one thread, so nothing is
//! atomic and nothing as large as the mesh is allocated. Where the chunks would have to be
//! read more than [`MAX_READS`] times in all (triangles in no order related to their
//! vertices), [`link_counts`] says so and the general path ([`super::links`]) is taken.

use super::fan::{link_entries, LinkCounts, Scratch};
use super::{is_good, CHUNK};
use rayon::prelude::*;

/// Vertices per tile: their rows (64 bytes a vertex) take 4 MiB. Smaller tiles (down to
/// 4096 vertices, rows in a core's L2) were no faster: the rows are written in nearly vertex
/// order.
pub(super) const TILE: usize = 1 << 16;

/// The most times the tiles may read the triangles in all (counting each chunk once for each
/// tile that reads it) before the general path is cheaper. An output of `extract` at 1024³
/// reads them about 1.2 times (docs/record/PERFORMANCE-history.md, "The output check, tile by
/// tile").
const MAX_READS: usize = 4;

/// Link entries a vertex keeps in its row. A vertex of a marching-cubes output has 6
/// triangles around it almost always and more than 8 rarely (at most 0.6 % of the vertices
/// of the dev corpus's outputs at 1024³); the entries beyond go to a short spill list.
const ROW: usize = 8;

/// The tiles whose vertices a chunk of triangles uses, as a bit set.
pub(super) struct TileSet(Vec<u64>);

impl TileSet {
    /// No tile of a mesh of `nv` vertices.
    pub(super) fn new(nv: usize) -> Self {
        Self(vec![0; nv.div_ceil(TILE).div_ceil(64)])
    }

    /// Adds the tile of vertex `v` (in range).
    #[inline]
    pub(super) fn insert(&mut self, v: u32) {
        let tile = v as usize / TILE;
        self.0[tile / 64] |= 1 << (tile % 64);
    }

    /// The tiles in the set, in increasing order.
    fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().enumerate().flat_map(|(w, &bits)| {
            (0..64)
                .filter(move |b| bits >> b & 1 == 1)
                .map(move |b| w * 64 + b)
        })
    }
}

/// The edge and vertex defects of the good triangles (in range, not degenerate), tile by
/// tile; `chunk_tiles[c]` holds the tiles that chunk `c` (of [`CHUNK`] triangles) uses.
/// `None` when the tiles would read the triangles more than [`MAX_READS`] times.
pub(super) fn link_counts(
    triangles: &[[u32; 3]],
    chunk_tiles: &[TileSet],
    nv: usize,
) -> Option<LinkCounts> {
    let mut readers: Vec<Vec<u32>> = vec![Vec::new(); nv.div_ceil(TILE)];
    let mut reads = 0usize;
    for (c, tiles) in chunk_tiles.iter().enumerate() {
        let len = chunk(triangles, c).len();
        for tile in tiles.iter() {
            readers[tile].push(c as u32);
            reads += len;
        }
    }
    if reads > MAX_READS * triangles.len() {
        return None;
    }
    Some(
        readers
            .par_iter()
            .enumerate()
            .map_init(TileLinks::default, |tile, (j, chunks)| {
                tile.counts(j, chunks, triangles, nv)
            })
            .reduce(LinkCounts::default, LinkCounts::sum),
    )
}

/// Chunk `c` of `triangles`.
fn chunk(triangles: &[[u32; 3]], c: usize) -> &[[u32; 3]] {
    let start = c * CHUNK;
    &triangles[start..(start + CHUNK).min(triangles.len())]
}

/// One vertex's first [`ROW`] link entries, on one cache line.
#[derive(Clone, Copy, Default)]
#[repr(align(64))]
struct Row([[u32; 2]; ROW]);

/// The links of one tile's vertices, reused from tile to tile by a thread.
#[derive(Default)]
struct TileLinks {
    /// Per vertex of the tile: its number of link entries.
    count: Vec<u32>,
    /// Per vertex of the tile: its first [`ROW`] entries.
    rows: Vec<Row>,
    /// `(vertex in the tile, entry)` for the entries beyond a full row.
    spill: Vec<(u32, [u32; 2])>,
    /// The link of a vertex with spilled entries, gathered.
    link: Vec<[u32; 2]>,
    scratch: Scratch,
}

impl TileLinks {
    /// Fills the links of tile `j` from the chunks numbered in `chunks` and counts them.
    fn counts(
        &mut self,
        j: usize,
        chunks: &[u32],
        triangles: &[[u32; 3]],
        nv: usize,
    ) -> LinkCounts {
        let lo = j * TILE;
        let len = TILE.min(nv - lo);
        self.count.clear();
        self.count.resize(len, 0);
        if self.rows.len() < len {
            self.rows.resize(len, Row::default());
        }
        self.spill.clear();
        for &c in chunks {
            for t in chunk(triangles, c as usize)
                .iter()
                .filter(|t| is_good(t, nv))
            {
                for (v, entry) in link_entries(t) {
                    let local = (v as usize).wrapping_sub(lo);
                    if local >= len {
                        continue;
                    }
                    let n = self.count[local] as usize;
                    self.count[local] += 1;
                    match self.rows[local].0.get_mut(n) {
                        Some(slot) => *slot = entry,
                        None => self.spill.push((local as u32, entry)),
                    }
                }
            }
        }
        // Spilled entries by vertex; a vertex's come after its row's, in the order of its
        // (ascending) position in the tile.
        self.spill.sort_unstable();
        let mut counts = LinkCounts::default();
        let mut spilled = 0;
        for (local, &n) in self.count.iter().enumerate() {
            let n = n as usize;
            let v = (lo + local) as u32;
            if n <= ROW {
                counts.add_vertex(v, &self.rows[local].0[..n], &mut self.scratch);
            } else {
                let extra = &self.spill[spilled..spilled + n - ROW];
                spilled += n - ROW;
                self.link.clear();
                self.link.extend_from_slice(&self.rows[local].0);
                self.link.extend(extra.iter().map(|&(_, e)| e));
                counts.add_vertex(v, &self.link, &mut self.scratch);
            }
        }
        counts
    }
}
