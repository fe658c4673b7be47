//! Volumetric locking, ν = 0.499: indentation of an irregular block. Placeholder filled below.
