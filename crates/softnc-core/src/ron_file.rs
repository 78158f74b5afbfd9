//! RON configuration files as softnc reads them: RON parsed with the path of a bad
//! field ([`parse_ron`]), and the one error ([`ConfigError`]) every section's
//! validation reports — the file, the RON path (`axes[1].max_acc_mm_per_s2`,
//! `force.controller.poles`) and what is wrong. Each algorithm crate owns its
//! section's schema and validation; the machine profile composes them.

/// Why a configuration (a machine profile, a daemon configuration, a section of
/// either) could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File name.
        file: String,
        /// Cause.
        source: std::io::Error,
    },
    /// The RON text does not parse or has a field of the wrong type or name.
    #[error("{file}: at `{path}`: {message}")]
    Parse {
        /// File name.
        file: String,
        /// RON path of the offending field (`axes[1].max_acc_mm_per_s2`), `.` for the root.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A field parses but its value is not acceptable.
    #[error("{file}: at `{path}`: {reason}")]
    Invalid {
        /// File name.
        file: String,
        /// RON path of the offending field.
        path: String,
        /// What is wrong and what is expected.
        reason: String,
    },
}

impl ConfigError {
    /// [`ConfigError::Invalid`]: the value at `path` of `file` is not acceptable.
    pub fn invalid(file: &str, path: impl Into<String>, reason: impl Into<String>) -> Self {
        ConfigError::Invalid {
            file: file.to_string(),
            path: path.into(),
            reason: reason.into(),
        }
    }
}

/// `v` (at `path` of `file`) must be a finite number > 0.
pub fn positive(v: f64, path: &str, file: &str) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::invalid(
            file,
            path,
            format!("must be a finite number > 0 (got {v})"),
        ))
    }
}

/// The text of the configuration file at `path`, with the file's name for messages;
/// a file that cannot be read is [`ConfigError::Io`].
pub fn read_text(path: &std::path::Path) -> Result<(String, String), ConfigError> {
    let file = path.display().to_string();
    match std::fs::read_to_string(path) {
        Ok(text) => Ok((file, text)),
        Err(source) => Err(ConfigError::Io { file, source }),
    }
}

/// Deserialize any RON document, reporting the path of a bad field.
pub fn parse_ron<T: serde::de::DeserializeOwned>(text: &str, file: &str) -> Result<T, ConfigError> {
    let mut de = ron::Deserializer::from_str(text).map_err(|e| ConfigError::Parse {
        file: format!("{file}:{}:{}", e.position.line, e.position.col),
        path: ".".into(),
        message: e.code.to_string(),
    })?;
    let value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = e.path().to_string();
        let message = e.into_inner().to_string();
        ConfigError::Parse {
            file: file.to_string(),
            path,
            message,
        }
    })?;
    de.end().map_err(|e| ConfigError::Parse {
        file: file.to_string(),
        path: ".".into(),
        message: format!("trailing text after the document: {e}"),
    })?;
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Axis {
        max_vel_mm_per_s: f64,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Doc {
        axes: Vec<Axis>,
    }

    #[test]
    fn a_bad_field_is_named_by_its_ron_path() {
        let text = "(axes: [(max_vel_mm_per_s: 1.0), (max_vel_mm_per_s: \"fast\")])";
        match parse_ron::<Doc>(text, "m.ron") {
            Err(ConfigError::Parse { file, path, .. }) => {
                assert_eq!(file, "m.ron");
                assert_eq!(path, "axes[1].max_vel_mm_per_s");
            }
            other => panic!("{other:?}"),
        }
        // a document cut short is refused, naming the file
        match parse_ron::<Doc>("(axes: [(max_vel_mm_per_s: 1.0)", "m.ron") {
            Err(ConfigError::Parse { file, .. }) => assert!(file.starts_with("m.ron"), "{file}"),
            other => panic!("{other:?}"),
        }
        assert!(parse_ron::<Doc>("(axes: []) x", "m.ron").is_err());
    }
}
