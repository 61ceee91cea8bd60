# Filter family kk (csrc/kk.h): not written yet.
