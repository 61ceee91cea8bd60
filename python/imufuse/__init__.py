"""imufuse: IMU fusion filters of OlliW's "IMU Data Fusing" article, as
embeddable C99 (imufuse_c) with bit-exact pure-Python references
(imufuse.reference)."""
__version__ = "0.1.0"
