// Stage markers inside delta6_solver.cpp and delta6_calibrated.cpp for the profile build of the benchmark
// (tools/bench_solver_avr.py --stages). Each marker writes its number to GPIOR0, which the
// simulator timestamps; the memory clobbers keep the solver's work between its markers.
// Only this build defines DELTA6_SOLVER_PROFILE; the portable core never depends on it.
#ifndef DELTA6_SOLVER_PROFILE_HOOKS_H
#define DELTA6_SOLVER_PROFILE_HOOKS_H

#include <avr/io.h>

enum : uint8_t {
    kProfileForwardKinematics = 11,  // after the joint terms (table trig, torques)
    kProfileQuadratic = 12,          // after the linear elimination
    kProfileStatics = 13,            // after the quadratic and its square root
    kProfileForceSum = 14,           // after the levers and the three divisions
    kProfileRotation = 15,           // after summing the link forces
    kProfileOutput = 16,             // after the rotation into {E}
};
// The calibrated solver's stages (delta6_calibrated.cpp).
enum : uint8_t {
    kProfileCalHistory = 21,         // after the history and the joint torques
    kProfileCalTrig = 22,            // after the table trig and the angle corrections
    kProfileCalTrilateration = 23,   // after the general trilateration
    kProfileCalStatics = 24,         // after the statics
    kProfileCalGimbal = 25,          // after the gimbal and the tilt
};

#define DELTA6_PROFILE_MARK(stage)          \
    do {                                    \
        asm volatile("" ::: "memory");      \
        GPIOR0 = (stage);                   \
        asm volatile("" ::: "memory");      \
    } while (0)

#endif  // DELTA6_SOLVER_PROFILE_HOOKS_H
