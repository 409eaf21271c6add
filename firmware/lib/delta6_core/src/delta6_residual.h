// The on-chip learned residual: a small integer network that corrects the wrench of the base
// model (calibrated or analytical) from that wrench, the encoder counts and their history.
//
// int8 weights, int32 accumulation, requantization by a Q15 multiplier and a shift, integer
// ReLU: no float inside, so the board, the host build of this file and the numpy reference
// (delta6.core.int8net) give the same integers. The only float steps are at the edges
// (quantizeInput, applyOutput), mirrored in float32 by the reference. A model comes from
// `delta6 codegen --model` (generated/delta6_model.h); docs/ondevice-model.md has the maths.
//
// Portable C++14: no Arduino headers, no heap, no STL; avr-gcc 5.4 and host g++.
#ifndef DELTA6_RESIDUAL_H
#define DELTA6_RESIDUAL_H

#include <stdint.h>

#if defined(__AVR__)
#include <avr/pgmspace.h>
#endif

namespace delta6 {
namespace residual {

// Bumped whenever Model or Layer change shape; the generated header checks it.
constexpr uint16_t kModelFormatVersion = 1;
// Board samples per model period at most (400 Hz for a model trained on 50 Hz logs).
constexpr uint8_t kMaxStride = 8;
// Widest layer (inputs or outputs): the activations live on the stack.
constexpr uint8_t kMaxWidth = 48;

enum FeatureKind : uint8_t {
    kFeatureWrench = 1,       // the base wrench, input steps
    kFeatureCounts = 2,       // signed count deltas
    kFeatureWrenchStep = 3,   // base wrench k-1 model periods ago minus k periods ago
    kFeatureCountStep = 4,    // the same for the counts
    kFeaturePlay = 5,         // counts minus a play operator of radius param (counts)
};

// Six features (one per axis or joint), each requantized int16 -> int8. In flash.
struct Feature {
    uint8_t kind;             // FeatureKind
    int16_t param;            // play radius (counts) or step period index k (1 or 2)
    int16_t multiplier[6];    // Q15, 2^14 <= m < 2^15
    uint8_t shift[6];         // 1..30
};

// A dense layer; the layer table and its arrays live in flash (DELTA6_FLASH).
struct Layer {
    uint8_t inputs;
    uint8_t outputs;
    uint8_t relu;             // 1: hidden (ReLU to int8 0..127); 0: the output (int16)
    const int8_t* weights;    // outputs x inputs, row-major
    const int32_t* bias;      // outputs
    const int16_t* multiplier;  // outputs, Q15
    const uint8_t* shift;     // outputs, 16..46
};

// The model; small, in RAM. Its pointers point into flash.
struct Model {
    uint16_t rate_hz;         // the rate the model was trained at (one model period)
    uint8_t feature_count;
    const Feature* features;
    uint8_t layer_count;
    const Layer* layers;
    const float* input_scale;   // 6: 1 / input step, base wrench (N, N*m) -> input steps
    const float* output_step;   // 6: correction step, N and N*m
    uint8_t history_length;   // ring entries (0: no step feature); kMaxStride * lag + 1
    uint8_t wrench_history;   // 1 if a wrench step needs the wrench ring
    uint8_t count_history;    // 1 if a count step needs the count ring
    uint8_t play_count;
};

// The state, in buffers the caller owns (sized by the generated header):
//   wrench_ring, count_ring: history_length x 6 int16 each (may be null if unused),
//   plays: play_count x 6 int16.
struct State {
    int16_t* wrench_ring;
    int16_t* count_ring;
    int16_t* plays;
    uint8_t head;             // ring index of the newest entry
    uint8_t stride;           // board samples per model period
    bool primed;              // false: the next step starts from rest
};

// round(acc * m / 2^shift), halves up, for int16 inputs (shift 1..30) and int32 accumulators
// (shift 16..46; m any int16): exact, from 32-bit products only.
int32_t requantize16(int16_t value, int16_t m, uint8_t shift);
int32_t requantize32(int32_t acc, int16_t m, uint8_t shift);

// Samples per model period at a board rate: max(1, round(rate / model rate)) <= kMaxStride.
uint8_t strideFor(const Model& model, uint16_t board_rate_hz);
// A new sample rate (or a new stream): set the stride and start from rest.
void configure(const Model& model, State& state, uint16_t board_rate_hz);
// Forget the history (a sample without a wrench): the next step starts from rest.
inline void reset(State& state) { state.primed = false; }

// One sample: base wrench in input steps and signed count deltas in, correction out (output
// steps). Updates the state.
void step(const Model& model, State& state, const int16_t base[6], const int16_t counts[6],
          int16_t correction[6]);

// The float edges: the base wrench in input steps (float32 product, lroundf, saturated), and
// wrench += correction * output step.
void quantizeInput(const Model& model, const float wrench[6], int16_t base[6]);
void applyOutput(const Model& model, const int16_t correction[6], float wrench[6]);

}  // namespace residual
}  // namespace delta6

#endif  // DELTA6_RESIDUAL_H
