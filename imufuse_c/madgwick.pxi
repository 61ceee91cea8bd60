# Filter family madgwick (csrc/madgwick.h): not written yet.
