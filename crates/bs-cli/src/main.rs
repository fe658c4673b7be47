//! `brainshift`: the command-line program.
fn main() {
    println!("brainshift");
}
