//! The `sparc3d` command line.
fn main() {
    println!("sparc3d");
}
