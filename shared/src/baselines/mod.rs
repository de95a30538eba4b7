//! Baseline simplifiers (being written).
