// A Madgwick AHRS filter in the style of the widely used Arduino library (a C++ class,
// begin(sampleFrequency), update() in deg/s, private quaternion, a fast inverse square root
// through a `long` type pun), written for imufuse's tests from the algorithm's equations:
// firmware as people carry it, which validate must handle from a declaration alone.
#ifndef MADGWICK_AHRS_H
#define MADGWICK_AHRS_H
#include <math.h>

class Madgwick {
private:
    static float invSqrt(float x);
    float beta;
    float q0, q1, q2, q3;
    float invSampleFreq;

public:
    Madgwick();
    void begin(float sampleFrequency) { invSampleFreq = 1.0f / sampleFrequency; }
    void update(float gx, float gy, float gz, float ax, float ay, float az, float mx, float my,
                float mz);
    void updateIMU(float gx, float gy, float gz, float ax, float ay, float az);
};

#endif
