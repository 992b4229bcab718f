//! What a row of the heading comparison is made of: a base heading and what is learnt
//! on top of it. The comparison's rows and the analysis's one choice of "best" hold this
//! typed key; its text (`raw`, `ellipse`, `ellipsoid+fourier`, `mlp`, `ahrs`, ...) is
//! written only at the edges: JSON, the page's element ids, the CLI's tables, and read
//! back from a user's `--heading-model`.

use std::fmt;

use serde::{Serialize, Serializer};

use super::Method;

/// The heading a row starts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseHeading {
    /// The levelled field without any calibration.
    Raw,
    /// A field-domain calibration of this log.
    Fitted(Method),
    /// An autopilot's calibration in force when the log was recorded.
    InForce,
    /// The attitude filter's yaw (its field corrected by the device calibration).
    Attitude,
}

/// What is learnt on top of a base heading from the reference.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnTop {
    Nothing,
    /// The PDR paper's Fourier deviation (Eq. 12).
    Fourier,
    /// The 2007 paper's network.
    Network,
}

/// A row of the heading comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowKey {
    pub base: BaseHeading,
    pub on_top: OnTop,
}

impl RowKey {
    /// The uncalibrated heading.
    pub const RAW: RowKey = RowKey::of(BaseHeading::Raw);
    /// The attitude filter's heading.
    pub const ATTITUDE: RowKey = RowKey::of(BaseHeading::Attitude);
    /// An autopilot's calibration in force.
    pub const IN_FORCE: RowKey = RowKey::of(BaseHeading::InForce);

    /// A base heading with nothing on top.
    pub const fn of(base: BaseHeading) -> RowKey {
        RowKey {
            base,
            on_top: OnTop::Nothing,
        }
    }

    /// A field-domain method's own row.
    pub const fn method(method: Method) -> RowKey {
        RowKey::of(BaseHeading::Fitted(method))
    }

    /// This row's base with `on_top` learnt on it.
    pub const fn with(self, on_top: OnTop) -> RowKey {
        RowKey {
            base: self.base,
            on_top,
        }
    }

    /// The field-domain method this row stands on, if any.
    pub fn field_method(self) -> Option<Method> {
        match self.base {
            BaseHeading::Fitted(method) => Some(method),
            _ => None,
        }
    }

    /// How much the row learns from the reference: the uncalibrated heading and an
    /// autopilot's calibration in force nothing, min/max two centres and scales, the
    /// ellipse, the 3D fit and the attitude filter a field shape (from the magnetometer
    /// alone), reference least squares its parameters from the reference; a Fourier
    /// model on top adds its terms, a network more. Ties between rows of about the same
    /// error go to the simpler.
    pub fn complexity(self) -> u32 {
        let base = match self.base {
            BaseHeading::Raw | BaseHeading::InForce => 0,
            BaseHeading::Fitted(Method::MinMax) => 1,
            BaseHeading::Fitted(Method::Ellipse | Method::Ellipsoid) | BaseHeading::Attitude => 2,
            BaseHeading::Fitted(Method::RefLs) => 3,
        };
        base + match self.on_top {
            OnTop::Nothing => 0,
            OnTop::Fourier => 1,
            OnTop::Network => 2,
        }
    }

    /// Whether the row's parameters are fitted on the reference heading (Eq. 8's least
    /// squares, the Fourier deviation of Eq. 12, the network), not on the field alone.
    pub fn learns_from_reference(self) -> bool {
        self.base == BaseHeading::Fitted(Method::RefLs) || self.on_top != OnTop::Nothing
    }

    /// The key as text: `raw`, `ellipse`, `ellipsoid+fourier`, `fourier` (on the
    /// uncalibrated heading), `mlp`, `in_force`, `ahrs`.
    pub fn text(self) -> String {
        self.to_string()
    }

    /// A key read back from its text; `None` for text that names no row.
    pub fn parse(text: &str) -> Option<RowKey> {
        let (base_text, on_top) = match text.split_once('+') {
            Some((base, "fourier")) => (base, OnTop::Fourier),
            Some((base, "mlp")) => (base, OnTop::Network),
            Some(_) => return None,
            None => match text {
                "fourier" => ("raw", OnTop::Fourier),
                "mlp" => ("raw", OnTop::Network),
                base => (base, OnTop::Nothing),
            },
        };
        let base = match base_text {
            "raw" => BaseHeading::Raw,
            "in_force" => BaseHeading::InForce,
            "ahrs" => BaseHeading::Attitude,
            other => BaseHeading::Fitted(
                Method::ALL
                    .into_iter()
                    .find(|method| method.key() == other)?,
            ),
        };
        Some(RowKey { base, on_top })
    }
}

impl fmt::Display for RowKey {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        let base = match self.base {
            BaseHeading::Raw => "raw",
            BaseHeading::Fitted(method) => method.key(),
            BaseHeading::InForce => "in_force",
            BaseHeading::Attitude => "ahrs",
        };
        match (self.base, self.on_top) {
            (_, OnTop::Nothing) => out.write_str(base),
            (BaseHeading::Raw, OnTop::Fourier) => out.write_str("fourier"),
            (BaseHeading::Raw, OnTop::Network) => out.write_str("mlp"),
            (_, OnTop::Fourier) => write!(out, "{base}+fourier"),
            (_, OnTop::Network) => write!(out, "{base}+mlp"),
        }
    }
}

impl Serialize for RowKey {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_key_reads_back_from_its_text() {
        let bases = [
            BaseHeading::Raw,
            BaseHeading::InForce,
            BaseHeading::Attitude,
            BaseHeading::Fitted(Method::MinMax),
            BaseHeading::Fitted(Method::Ellipse),
            BaseHeading::Fitted(Method::Ellipsoid),
            BaseHeading::Fitted(Method::RefLs),
        ];
        for base in bases {
            for on_top in [OnTop::Nothing, OnTop::Fourier, OnTop::Network] {
                let key = RowKey { base, on_top };
                assert_eq!(RowKey::parse(&key.text()), Some(key), "{key}");
            }
        }
        assert_eq!(RowKey::RAW.with(OnTop::Fourier).text(), "fourier");
        assert_eq!(
            RowKey::method(Method::Ellipsoid)
                .with(OnTop::Fourier)
                .text(),
            "ellipsoid+fourier"
        );
        assert_eq!(RowKey::parse("ellipsoid+rls"), None);
        assert_eq!(RowKey::parse("compass"), None);
    }

    #[test]
    fn complexity_and_learning_follow_the_parts() {
        let ellipse = RowKey::method(Method::Ellipse);
        assert_eq!(RowKey::RAW.complexity(), 0);
        assert_eq!(RowKey::RAW.with(OnTop::Fourier).complexity(), 1);
        assert_eq!(ellipse.with(OnTop::Network).complexity(), 4);
        assert!(!ellipse.learns_from_reference());
        assert!(ellipse.with(OnTop::Fourier).learns_from_reference());
        assert!(RowKey::method(Method::RefLs).learns_from_reference());
    }
}
