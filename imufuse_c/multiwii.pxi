# Filter family multiwii (csrc/multiwii.h): not written yet.
