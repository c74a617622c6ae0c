//! harmonid-sim (work in progress).
