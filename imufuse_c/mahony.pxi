# Filter family mahony (csrc/mahony.h): not written yet.
