//! Sanitising raw meshes: drop faces with out-of-range indices or non-finite corners.
