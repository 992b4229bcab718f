//! Column mappings remembered between runs, keyed by the header they were made for, in
//! `$XDG_CONFIG_HOME/compass-pdr/mappings.json` (or `~/.config/…`). A missing, unreadable
//! or old file is ignored with a warning, never an error: it only saves typing.

use std::collections::BTreeMap;
use std::path::PathBuf;

use compass_pdr::io::delimited::ColumnMapping;
use serde::{Deserialize, Serialize};

/// The file's schema version; a file of another version is ignored.
const VERSION: u32 = 1;

#[derive(Debug, Default, Serialize, Deserialize)]
struct StoredMappings {
    version: u32,
    /// Header signature (lower-cased column names) to mapping.
    by_header: BTreeMap<String, ColumnMapping>,
}

pub struct MappingStore {
    path: Option<PathBuf>,
    stored: StoredMappings,
    changed: bool,
}

impl MappingStore {
    pub fn load() -> MappingStore {
        let path = config_dir().map(|dir| dir.join("compass-pdr").join("mappings.json"));
        let stored = match path.as_ref().map(std::fs::read_to_string) {
            Some(Ok(text)) => match serde_json::from_str::<StoredMappings>(&text) {
                Ok(stored) if stored.version == VERSION => stored,
                Ok(stored) => {
                    eprintln!("warning: ignoring remembered column mappings of version {} (this is version {VERSION})", stored.version);
                    StoredMappings::default()
                }
                Err(error) => {
                    eprintln!("warning: ignoring unreadable remembered column mappings: {error}");
                    StoredMappings::default()
                }
            },
            _ => StoredMappings::default(),
        };
        MappingStore {
            path,
            stored: StoredMappings {
                version: VERSION,
                ..stored
            },
            changed: false,
        }
    }

    pub fn recall(&self, signature: &str) -> Option<ColumnMapping> {
        self.stored.by_header.get(signature).cloned()
    }

    pub fn remember(&mut self, signature: &str, mapping: &ColumnMapping) {
        if self.stored.by_header.get(signature) != Some(mapping) {
            self.stored
                .by_header
                .insert(signature.to_string(), mapping.clone());
            self.changed = true;
        }
    }

    pub fn path_text(&self) -> String {
        self.path
            .as_ref()
            .map_or("nowhere".to_string(), |path| path.display().to_string())
    }

    pub fn save_if_changed(&self) -> Result<(), String> {
        let Some(path) = self.path.as_ref().filter(|_| self.changed) else {
            return Ok(());
        };
        let cannot = |error: &dyn std::fmt::Display| {
            format!(
                "could not remember the column mapping in {}: {error}",
                path.display()
            )
        };
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|error| cannot(&error))?;
        }
        let text = serde_json::to_string_pretty(&self.stored).map_err(|error| cannot(&error))?;
        std::fs::write(path, text + "\n").map_err(|error| cannot(&error))
    }
}

fn config_dir() -> Option<PathBuf> {
    std::env::var_os("XDG_CONFIG_HOME")
        .filter(|dir| !dir.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|home| PathBuf::from(home).join(".config")))
}
