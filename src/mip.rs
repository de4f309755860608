//! Mip pyramid (being written).
