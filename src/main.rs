//! `limot`: command-line interface.

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "limot",
    version,
    about = "LiDAR-inertial odometry and multi-object tracking, with a simulation testbed"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the version of every component.
    Version,
}

fn main() {
    let cli = Cli::parse();
    match cli.command {
        Command::Version => println!("limot {}", env!("CARGO_PKG_VERSION")),
    }
}
