//! One item: its bytes from disk or a URL ([`source`]), its conversion, the one function that
//! touches geometry ([`convert`]), and its quality columns ([`quality`]).

pub mod appearance;
pub mod convert;
pub mod quality;
pub mod row;
pub mod source;
pub mod steps;
