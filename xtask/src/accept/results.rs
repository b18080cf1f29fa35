//! Where a scenario's run goes: its section of `docs/results.md` and the README's status table, kept by
//! [`crate::board::page`].

use std::path::Path;

/// Writes `md` as the section of scenario `name` of `docs/results.md` ([`crate::board::page::record`]).
pub(crate) fn record(root: &Path, name: &str, md: &str) -> Result<(), String> {
    crate::board::page::record(root, name, md, &crate::accept::SCENARIOS)
}

/// `cargo xtask status` ([`crate::board::page::update_readme`]).
pub fn update_readme(root: &Path) -> Result<(), String> {
    crate::board::page::update_readme(root, &crate::accept::SCENARIOS)
}
