//! Where Lightloom keeps its own files for a user, by the XDG base-directory rules.

use std::path::PathBuf;

/// `$OWN` when set, else `$XDG/lightloom`, else `~/<home_relative>/lightloom` (under the
/// temporary folder without a home).
pub fn user_dir(own: &str, xdg: &str, home_relative: &str) -> PathBuf {
    let set = |var: &str| std::env::var_os(var).filter(|d| !d.is_empty()).map(PathBuf::from);
    if let Some(dir) = set(own) {
        return dir;
    }
    if let Some(dir) = set(xdg) {
        return dir.join("lightloom");
    }
    set("HOME").unwrap_or_else(std::env::temp_dir).join(home_relative).join("lightloom")
}
