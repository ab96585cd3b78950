//! Checking outputs: pymeshlab validation, pictures of a source and its output, their colours.

pub mod colours;
pub mod pictures;
pub mod validation;
