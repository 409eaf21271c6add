// C ABI over the residual engine (delta6_residual.cpp) for the ctypes cross-checks against
// the numpy reference (delta6.build.nativeresidual). A session holds a network built at run
// time from flat arrays (on the host "flash" is plain memory) and its state, so a stream can
// be fed in pieces. Host only: it uses the heap, the engine does not.
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <new>

#include "delta6_residual.h"
#if defined(D6R_GENERATED)
#include "generated/delta6_model.h"
#endif

namespace r = delta6::residual;

namespace {

const uint8_t kMaxFeatures = r::kMaxWidth / 6;
const uint8_t kMaxLayers = 8;
const size_t kMaxWeights = static_cast<size_t>(kMaxLayers) * r::kMaxWidth * r::kMaxWidth;

struct Session {
    r::Feature features[kMaxFeatures];
    r::Layer layers[kMaxLayers];
    int8_t weights[kMaxWeights];
    int32_t bias[kMaxLayers * r::kMaxWidth];
    int16_t multiplier[kMaxLayers * r::kMaxWidth];
    uint8_t shift[kMaxLayers * r::kMaxWidth];
    float input_scale[6];
    float output_step[6];
    r::Model model;
    int16_t wrench_ring[(2 * r::kMaxStride + 1) * 6];
    int16_t count_ring[(2 * r::kMaxStride + 1) * 6];
    int16_t plays[kMaxFeatures * 6];
    r::State state;
};

}  // namespace

extern "C" {

int32_t d6r_requantize16(int16_t value, int16_t m, uint8_t shift) {
    return r::requantize16(value, m, shift);
}

int32_t d6r_requantize32(int32_t acc, int16_t m, uint8_t shift) {
    return r::requantize32(acc, m, shift);
}

// kinds/params: nf feature groups; fmult/fshift: nf x 6. dims: nl + 1 widths; relu: nl flags;
// weights, bias, lmult, lshift: the layers' arrays concatenated. Returns NULL if too big.
void* d6r_create(uint16_t rate_hz, uint8_t nf, const uint8_t* kinds, const int16_t* params,
                 const int16_t* fmult, const uint8_t* fshift, uint8_t nl, const uint8_t* dims,
                 const uint8_t* relu, const int8_t* weights, const int32_t* bias,
                 const int16_t* lmult, const uint8_t* lshift, const float* input_scale,
                 const float* output_step, uint8_t history_length, uint16_t board_rate_hz) {
    if (nf > kMaxFeatures || nl > kMaxLayers || history_length > 2 * r::kMaxStride + 1) {
        return nullptr;
    }
    Session* s = new (std::nothrow) Session();
    if (!s) return nullptr;
    uint8_t plays = 0;
    bool wrench_history = false, count_history = false;
    for (uint8_t g = 0; g < nf; ++g) {
        r::Feature& f = s->features[g];
        f.kind = kinds[g];
        f.param = params[g];
        memcpy(f.multiplier, fmult + 6 * g, sizeof f.multiplier);
        memcpy(f.shift, fshift + 6 * g, sizeof f.shift);
        if (f.kind == r::kFeaturePlay) ++plays;
        if (f.kind == r::kFeatureWrenchStep) wrench_history = true;
        if (f.kind == r::kFeatureCountStep) count_history = true;
    }
    size_t w = 0, o = 0;
    for (uint8_t l = 0; l < nl; ++l) {
        const size_t size = static_cast<size_t>(dims[l]) * dims[l + 1];
        if (w + size > kMaxWeights) {
            delete s;
            return nullptr;
        }
        memcpy(s->weights + w, weights + w, size);
        memcpy(s->bias + o, bias + o, dims[l + 1] * sizeof(int32_t));
        memcpy(s->multiplier + o, lmult + o, dims[l + 1] * sizeof(int16_t));
        memcpy(s->shift + o, lshift + o, dims[l + 1]);
        s->layers[l] = {dims[l], dims[l + 1], relu[l], s->weights + w, s->bias + o,
                        s->multiplier + o, s->shift + o};
        w += size;
        o += dims[l + 1];
    }
    memcpy(s->input_scale, input_scale, sizeof s->input_scale);
    memcpy(s->output_step, output_step, sizeof s->output_step);
    s->model = {rate_hz, nf, s->features, nl, s->layers, s->input_scale, s->output_step,
                history_length, static_cast<uint8_t>(wrench_history),
                static_cast<uint8_t>(count_history), plays};
    s->state = {s->wrench_ring, s->count_ring, s->plays, 0, 1, false};
    r::configure(s->model, s->state, board_rate_hz);
    return s;
}

#if defined(D6R_GENERATED)
// A session on the generated header's model (delta6::model::kModel) instead of run-time arrays.
void* d6r_create_generated(uint16_t board_rate_hz) {
    Session* s = new (std::nothrow) Session();
    if (!s) return nullptr;
    s->model = delta6::model::kModel;
    s->state = {s->wrench_ring, s->count_ring, s->plays, 0, 1, false};
    r::configure(s->model, s->state, board_rate_hz);
    return s;
}

uint32_t d6r_generated_hash() { return delta6::model::kHash; }
#endif

void d6r_destroy(void* session) { delete static_cast<Session*>(session); }

uint8_t d6r_stride(void* session) { return static_cast<Session*>(session)->state.stride; }

// n samples; valid[i] == 0: no base wrench (correction 0, state reset), as the firmware does.
void d6r_feed(void* session, size_t n, const int16_t* base, const int16_t* counts,
              const uint8_t* valid, int16_t* correction) {
    Session* s = static_cast<Session*>(session);
    for (size_t i = 0; i < n; ++i) {
        if (valid[i]) {
            r::step(s->model, s->state, base + 6 * i, counts + 6 * i, correction + 6 * i);
        } else {
            r::reset(s->state);
            memset(correction + 6 * i, 0, 6 * sizeof(int16_t));
        }
    }
}

void d6r_quantize_input(void* session, size_t n, const float* wrench, int16_t* base) {
    Session* s = static_cast<Session*>(session);
    for (size_t i = 0; i < n; ++i) r::quantizeInput(s->model, wrench + 6 * i, base + 6 * i);
}

void d6r_apply_output(void* session, size_t n, const int16_t* correction, float* wrench) {
    Session* s = static_cast<Session*>(session);
    for (size_t i = 0; i < n; ++i) r::applyOutput(s->model, correction + 6 * i, wrench + 6 * i);
}

}  // extern "C"
