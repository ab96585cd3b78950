//! Marching-cubes triangulation table, generated so that ambiguous faces are resolved the same
//! way from both cells that share them.
