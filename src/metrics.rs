//! Image metrics (being written).
