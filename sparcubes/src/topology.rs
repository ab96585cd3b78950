//! Topological checks on triangle meshes: half-edge closedness, 2-manifoldness, components.
