//! The isolated process an item converts in: the child's side ([`child`]), the parent's
//! ([`parent`]), the one child-process supervisor ([`process`]: stderr tail, parent-death
//! signal, time limit, resource use) and the item supervisor ([`supervisor`]: items in a child
//! with a watchdog, its deaths classified).

pub mod child;
pub mod parent;
pub mod process;
pub mod supervisor;
