//! `cta`: the command-line tool of the NorthStar characterization test apparatus.

fn main() {
    cta_cli::main();
}
