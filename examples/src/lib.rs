//! Shared parts of the example programs (`src/bin/*`): the `--window` viewer.

pub mod window;
