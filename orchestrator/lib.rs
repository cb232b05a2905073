//! `glint`: deploys the characterization chain as separate processes over iceoryx2 shared
//! memory, supervises them, and writes a report. Also the entry point of every service
//! (`glint service <name>`), so one executable ships the whole chain. The binary is
//! `orchestrator/main.rs`, a call of [`main`]; this library also gives other tools and the
//! system tests the report's types ([`report::Report`]).
//!
//! Exit codes: 0 success, 1 the run failed (a service died, a message was lost, …),
//! 2 bad input (scenario file, arguments).

mod bench;
mod cli;
#[cfg(feature = "lab")]
mod lab;
mod plots;
mod png;
mod progress;
pub mod report;
/// A [001] campaign's `campaign.json`, where other tools look for it.
#[cfg(feature = "lab")]
pub use lab::photometry::PhotometryCampaign;
/// A [004] campaign's `campaign.json`, where other tools look for it.
#[cfg(feature = "lab")]
pub use lab::relnav::RelNavCampaign;
/// The fault matrix's report, where other tools look for it.
pub use run::matrix;
pub mod run;
mod service;
mod tools;
mod top;

use std::process::ExitCode;

use clap::Parser;
use cli::{Cli, Cmd};

/// `glint` with the process's arguments.
pub fn main() -> ExitCode {
    match Cli::parse().command {
        Cmd::Run(args) => run::command::command(args),
        Cmd::Replay(args) => run::replay::command(args),
        Cmd::Top { prefix, once, json } => top::command(prefix, once, json),
        Cmd::Clean { prefix, list } => run::clean::command(prefix, list),
        Cmd::Validate { scenario } => run::command::validate(scenario),
        Cmd::Report { schema } => report::command(schema),
        Cmd::Invert(args) => tools::invert::command(args),
        #[cfg(feature = "lab")]
        Cmd::Lab { lab } => lab::command(lab),
        Cmd::Bench { bench } => bench::command(bench),
        Cmd::BenchPeer(args) => bench::ipc::peer_command(args),
        Cmd::Tool { tool } => tools::command(tool),
        Cmd::Service(args) => service::command(args),
    }
}
