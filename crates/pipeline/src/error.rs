//! The library's errors: what went wrong, by kind, with a message that names the file or the setting. The
//! cause of a failure in a library crate (a format, the simulator, a fit) is kept as the error's source, so
//! a front end can print the chain (`anyhow`'s `{:#}`) or walk it ([`Error::chain`]).

/// Why a stage stopped.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An input file or folder is missing, unreadable or wrong: the message names it and the problem.
    #[error("{0}")]
    Input(String),
    /// A setting is out of range, or inputs that do not go together were asked for.
    #[error("{0}")]
    Settings(String),
    /// The output folder holds another run (other inputs or settings): nothing was written.
    #[error("{0}")]
    OutputTaken(String),
    /// A stage of the method could not go on (an empty mask where a pose is fitted, a fit with nothing to
    /// fit, a stage asked for before the one it needs).
    #[error("{0}")]
    Stage(String),
    /// What was being done when `source` failed (`cannot read FILE`, `demo stage "fit slide" failed`).
    #[error("{context}")]
    Context {
        context: String,
        #[source]
        source: Box<Error>,
    },
    /// A failure in a library crate (formats, fields, the simulator, the fits), as it said it.
    #[error(transparent)]
    Library(Box<dyn std::error::Error + Send + Sync + 'static>),
}

/// The library's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// The message and every cause after it, joined by `: ` (what the CLI prints).
    pub fn chain(&self) -> String {
        let mut text = self.to_string();
        let mut cause = std::error::Error::source(self);
        while let Some(c) = cause {
            text.push_str(": ");
            text.push_str(&c.to_string());
            cause = c.source();
        }
        text
    }

    /// `source` under the context `context`.
    pub fn context(context: impl Into<String>, source: impl Into<Error>) -> Error {
        Error::Context {
            context: context.into(),
            source: Box::new(source.into()),
        }
    }
}

macro_rules! library_errors {
    ($($t:ty),* $(,)?) => {$(
        impl From<$t> for Error {
            fn from(e: $t) -> Error {
                Error::Library(Box::new(e))
            }
        }
    )*};
}

library_errors!(
    std::io::Error,
    std::fmt::Error,
    serde_json::Error,
    toml::ser::Error,
    toml::de::Error,
    pganeus_io::IoError,
    geom::CameraError,
    sim::BodyError,
    sim::ConfigError,
    sim::MeshCheckError,
    sim::sdf::GridError,
    sim::sdf::MeshSdfError,
    neus::DatasetError,
    neus::ConfigError,
    neus::ObjectError,
    neus::TrainError,
    neus::checkpoint::CheckpointError,
    mesh::GridError,
    mesh::MergeError,
    mesh::merge::PartError,
    recon::FrameError,
    recon::PoseFitError,
    recon::FitError,
    recon::poses_from_video::PosesFromVideoError,
    recon::physics_from_video::VideoPhysicsError,
    scene_file::SceneError,
    synth::SynthError,
);

/// `context` / `with_context` on results, as `anyhow` has them: the error becomes the source of one that says
/// what was being done.
pub trait Context<T> {
    fn context(self, context: impl Into<String>) -> Result<T>;
    fn with_context<S: Into<String>>(self, context: impl FnOnce() -> S) -> Result<T>;
}

impl<T, E: Into<Error>> Context<T> for std::result::Result<T, E> {
    fn context(self, context: impl Into<String>) -> Result<T> {
        self.map_err(|e| Error::context(context, e))
    }

    fn with_context<S: Into<String>>(self, context: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| Error::context(context(), e))
    }
}

/// `return Err(Error::KIND(format!(...)))`.
macro_rules! fail {
    ($kind:ident, $($fmt:tt)+) => {
        return Err($crate::Error::$kind(format!($($fmt)+)))
    };
}

/// `Error::KIND(format!(...))`.
macro_rules! err {
    ($kind:ident, $($fmt:tt)+) => {
        $crate::Error::$kind(format!($($fmt)+))
    };
}

pub(crate) use {err, fail};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chain_names_each_cause_once() {
        let read: std::result::Result<(), std::io::Error> = Err(std::io::Error::other("no such file"));
        let e = read.context("cannot read fit.toml").unwrap_err();
        assert_eq!(e.to_string(), "cannot read fit.toml");
        assert_eq!(e.chain(), "cannot read fit.toml: no such file");
        let e = Error::context("demo stage \"fit\" failed", e);
        assert_eq!(
            e.chain(),
            "demo stage \"fit\" failed: cannot read fit.toml: no such file"
        );
    }
}
