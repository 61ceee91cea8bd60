# Filter family dcm (csrc/dcm.h): not written yet.
