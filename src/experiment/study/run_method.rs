//! The methods of a study: sigmap's own map builders and the external
//! mappers of the experiment's `[[mapper]]` tables, under one name each.

use crate::experiment::run::external::ExternalMapper;
use crate::mapping::Method;
use std::fmt;
use std::sync::Arc;

/// A method of an experiment: its rows in runs.csv, summary.csv and
/// paired.csv carry its name.
#[derive(Clone, Debug, PartialEq)]
pub enum RunMethod {
    /// One of sigmap's own methods.
    Own(Method),
    /// A program of the experiment's `[[mapper]]` table.
    External(Arc<ExternalMapper>),
}

impl RunMethod {
    /// Its name in files and tables.
    pub fn as_str(&self) -> &str {
        match self {
            RunMethod::Own(method) => method.as_str(),
            RunMethod::External(mapper) => &mapper.name,
        }
    }

    /// sigmap's own method, if it is one.
    pub fn own(&self) -> Option<Method> {
        match self {
            RunMethod::Own(method) => Some(*method),
            RunMethod::External(_) => None,
        }
    }
}

impl From<Method> for RunMethod {
    fn from(method: Method) -> Self {
        RunMethod::Own(method)
    }
}

impl fmt::Display for RunMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
