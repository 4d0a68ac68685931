//! Studies of the radiosity engine: the solver comparison (error against time and
//! iterations, plotted) and progressive image sequences with their contact sheet — the
//! pictures of the lecture — false-colour illuminance pictures for lighting design, and an
//! independent path tracer for per-polygon reference radiosities. They watch the library's own solvers through its observer; the
//! plotting and font dependencies live here, not in the core library.

pub mod compare;
pub mod falsecolour;
pub mod font;
pub mod path_trace;
pub mod sequence;
