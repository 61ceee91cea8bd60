# Filter family mahony2d (csrc/mahony2d.h): not written yet.
