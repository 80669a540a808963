//! The library's errors as Python exceptions: one class per kind of [`pipeline::Error`], all under
//! `PganeusError`, each carrying the message the command prints (the error and its causes).

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    pganeus,
    PganeusError,
    PyException,
    "A stage, a file or a setting of pganeus failed; the message names the file or the setting."
);
create_exception!(
    pganeus,
    InputError,
    PganeusError,
    "An input file or folder is missing, unreadable or wrong."
);
create_exception!(
    pganeus,
    SettingsError,
    PganeusError,
    "A setting is out of range, or settings that do not go together were given."
);
create_exception!(
    pganeus,
    OutputTakenError,
    PganeusError,
    "The output folder holds another run (other inputs or settings): nothing was written."
);
create_exception!(
    pganeus,
    StageError,
    PganeusError,
    "A stage of the method could not go on (an empty mask, nothing to fit, a stage before the one it needs)."
);

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("PganeusError", py.get_type::<PganeusError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("SettingsError", py.get_type::<SettingsError>())?;
    m.add("OutputTakenError", py.get_type::<OutputTakenError>())?;
    m.add("StageError", py.get_type::<StageError>())?;
    Ok(())
}

/// The exception for `e`: the class of its innermost kind (a context names what was being done, its source
/// says what went wrong), the whole chain as the message.
pub fn to_py(e: &pipeline::Error) -> PyErr {
    let message = e.chain();
    let mut kind = e;
    while let pipeline::Error::Context { source, .. } = kind {
        kind = source;
    }
    match kind {
        pipeline::Error::Input(_) => InputError::new_err(message),
        pipeline::Error::Settings(_) => SettingsError::new_err(message),
        pipeline::Error::OutputTaken(_) => OutputTakenError::new_err(message),
        pipeline::Error::Stage(_) => StageError::new_err(message),
        // A file the formats could not open or read is an input's fault too.
        pipeline::Error::Library(e) if e.is::<pganeus_io::IoError>() || e.is::<std::io::Error>() => {
            InputError::new_err(message)
        }
        pipeline::Error::Library(e)
            if e.is::<sim::sdf::GridError>()
                || e.is::<scene_file::SceneError>()
                || e.is::<neus::DatasetError>()
                || e.is::<neus::checkpoint::CheckpointError>() =>
        {
            InputError::new_err(message)
        }
        _ => PganeusError::new_err(message),
    }
}

/// A file the project reads could not be read: an `InputError` naming it.
pub fn input(message: impl std::fmt::Display) -> PyErr {
    InputError::new_err(message.to_string())
}
