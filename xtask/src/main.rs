//! Project automation. Run `cargo xtask help`.

fn main() {
    println!("xtask: not yet");
}
