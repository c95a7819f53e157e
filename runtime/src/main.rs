//! `companion`: run the HIL demo, the paper's simulations, and the latency benchmark.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
