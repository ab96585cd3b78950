//! The output mesh in colour: `convert --attributes` and `show` of an item with attributes
//! write each vertex with the base colour and alpha of its cell where the format holds vertex
//! colours, and say so where it does not.

use sparcubes::attributes::CellAttributes;
use sparcubes::cubes::SparseCubes;
use sparcubes::TriMesh;
use std::path::Path;

/// The colours of `mesh`'s vertices (in the grid frame) from the cells' attributes
/// ([`sparcubes::attributes::vertex_colours::vertex_colours`]); a note on stderr when the
/// format of `output` cannot hold them (STL), which is then written without them.
pub fn of_vertices(
    cubes: &SparseCubes,
    cells: &CellAttributes,
    mesh: &TriMesh,
    output: &Path,
) -> Vec<[u8; 4]> {
    if !sparcubes::io::holds_colours(output) {
        eprintln!(
            "note: {} holds no vertex colours, so the mesh is written without the cells' \
             colours (write .ply, .obj or .glb to see them)",
            output.display()
        );
    }
    sparcubes::attributes::vertex_colours::vertex_colours(cubes, cells, mesh)
}
