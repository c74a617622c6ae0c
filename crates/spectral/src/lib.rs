//! harmonid-spectral (work in progress).
