//! The `glint` executable: the orchestrator, the offline tools and every service
//! (`glint service <name>`) in one binary. Its code is the `glint` library (orchestrator/lib.rs).

fn main() -> std::process::ExitCode {
    glint::main()
}
