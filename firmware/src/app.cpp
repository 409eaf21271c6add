#include "app.h"

#include "board.h"
#include "board_contract.h"
#include "delta6_device.h"
#include "delta6_encoder.h"
#include "delta6_solver.h"
#include "delta6_version.h"
#include "generated/delta6_design.h"

// A unit's calibration, when `delta6 codegen --calibration` put one next to the design header
// (docs/calibration.md); without it the firmware is the plain analytical one.
#if defined(__has_include)
#if __has_include("generated/delta6_calibration.h")
#include "delta6_calibrated.h"
#include "generated/delta6_calibration.h"
#define DELTA6_CALIBRATED 1
#endif
// An on-chip residual model over the base wrench (analytical or calibrated), when
// `delta6 codegen --model` put one next to the design header (docs/ondevice-model.md); without
// it the firmware is exactly the one without a model.
#if __has_include("generated/delta6_model.h")
#include "delta6_residual.h"
#include "generated/delta6_model.h"
#define DELTA6_RESIDUAL 1
#endif
#endif

// The fastest rate the board sustains without overruns in both stream modes, for the info
// record and the START check, at 16 MHz and scaled with the clock
// (tools/bench_virtual_board.py [--calibration CAL --model M] on the emulated ATmega328P; the
// 4809 runs the same code within about 10 %):
// - the analytical model: 350 Hz (wrench streams sustain 400 Hz, wrench+raw 350 Hz);
// - a calibrated unit: 250 Hz (the calibrated solve is about 44,000 cycles of the 64,000 in a
//   250 Hz period; a wrench+raw sample about 50,000 with the record; with every joint moving
//   and reversing every sample the CPU is about 90 % busy);
// - a calibrated unit with curve tables (a nonlinear spring or an encoder's periodic error):
//   250 Hz too (the tables add about 2,500 cycles a sample: with every joint moving and
//   reversing every sample the CPU is 92-93 % busy, 7-8 % spare; docs/calibration.md,
//   "The worst case at 250 Hz");
// - with an on-chip residual (over either model): 200 Hz (over a calibration the default
//   residual adds about 8,500; codegen refuses models too costly for 200 Hz).
// With the wrench pipeline on (a low-pass filter or a tool frame: about 19,000 more cycles
// per sample): 250 Hz for the analytical model (300 Hz overruns), 150 Hz calibrated.
#if DELTA6_RESIDUAL
#define DELTA6_RATED_HZ 200UL
#define DELTA6_RATED_PIPELINE_HZ 150UL
#elif defined(DELTA6_CALIBRATION_CURVES)
#define DELTA6_RATED_HZ 250UL
#define DELTA6_RATED_PIPELINE_HZ 150UL
#elif DELTA6_CALIBRATED
#define DELTA6_RATED_HZ 250UL
#define DELTA6_RATED_PIPELINE_HZ 150UL
#else
#define DELTA6_RATED_HZ 350UL
#define DELTA6_RATED_PIPELINE_HZ 250UL
#endif
#ifndef DELTA6_MAX_RATE_HZ
#define DELTA6_MAX_RATE_HZ (DELTA6_RATED_HZ * (F_CPU / 1000000UL) / 16UL)
#endif
#ifndef DELTA6_MAX_RATE_PIPELINE_HZ
#define DELTA6_MAX_RATE_PIPELINE_HZ (DELTA6_RATED_PIPELINE_HZ * (F_CPU / 1000000UL) / 16UL)
#endif
// The rate a fresh board streams at: 250 Hz, or the board's highest if that is lower.
#ifndef DELTA6_DEFAULT_RATE_HZ
#define DELTA6_DEFAULT_RATE_HZ (DELTA6_MAX_RATE_HZ < 250UL ? DELTA6_MAX_RATE_HZ : 250UL)
#endif

namespace {

namespace d = delta6::design;

const uint8_t kQueueLength = 4;   // a power of two; a ring of 4 holds 3 latched samples
const uint16_t kEepromAddress = 0;
// Received bytes fed to the device per loop turn. Most bytes cost ~100 cycles; the one that
// completes a command runs it (GET_INFO: ~19,000 cycles).
const uint8_t kBytesPerTurn = 32;

// One latched sample: what the timer interrupt leaves for the main loop.
struct Latched {
  uint32_t time_us;
  uint16_t word[6];
  uint16_t inverse[6];
  uint8_t missed;   // periods lost (queue full) since the previous latched sample
};

Latched queue[kQueueLength];
volatile uint8_t queue_head = 0;   // written by the interrupt
volatile uint8_t queue_tail = 0;   // written by the main loop
volatile uint8_t missed = 0;
volatile bool latching = false;

#if DELTA6_CALIBRATED || DELTA6_RESIDUAL
// The zero counts the calibrated model's and the residual's histories were built on (a new
// zero restarts them): one copy for both.
uint16_t model_zero[6];

// Whether the device's zero counts changed since the last sample that had all six angles.
bool zeroChanged(const uint16_t* zero) {
  bool changed = false;
  for (uint8_t j = 0; j < 6; ++j) {
    if (zero[j] != model_zero[j]) changed = true;
    model_zero[j] = zero[j];
  }
  return changed;
}
#endif

#if DELTA6_CALIBRATED
// The calibrated model's history.
delta6::CalibrationState calibration_state;
#endif

#if DELTA6_RESIDUAL
namespace m = delta6::model;
// The residual's history (rings sized for the model's deepest look-back at kMaxStride).
int16_t residual_wrench_ring[m::kWrenchHistory ? 6 * m::kHistoryLength : 1];
int16_t residual_count_ring[m::kCountHistory ? 6 * m::kHistoryLength : 1];
int16_t residual_plays[m::kPlayCount ? 6 * m::kPlayCount : 1];
delta6::residual::State residual_state = {residual_wrench_ring, residual_count_ring,
                                          residual_plays, 0, 1, false};

// The base wrench plus the model's correction; a sample without a wrench, or a new zero,
// restarts the history.
void applyResidual(bool solver_ok, bool zero_changed, const int16_t* delta, float* wrench) {
  if (zero_changed || !solver_ok) delta6::residual::reset(residual_state);
  if (!solver_ok) return;
  int16_t base[6] = {0, 0, 0, 0, 0, 0};
  int16_t correction[6];
  // A model that never reads the base wrench (e.g. a linear map of the counts) saves the
  // float quantization: its outputs do not depend on `base`.
  if (m::kUsesWrench) delta6::residual::quantizeInput(m::kModel, wrench, base);
  delta6::residual::step(m::kModel, residual_state, base, delta, correction);
  delta6::residual::applyOutput(m::kModel, correction, wrench);
}
#endif

class BoardHardware : public delta6::Hardware {
 public:
  uint16_t txSpace() override { return board::txSpace(); }
  void txWrite(const uint8_t* data, uint16_t n) override {
    board::txWrite(data, n);
    // A whole data record: it ends in the delimiter (INFO goes out in pieces, which do not),
    // data[0] is the COBS code byte, data[1] the record type (never 0, so never stuffed).
    if (n > 1 && data[n - 1] == 0 &&
        (data[1] == delta6::proto::kWrench || data[1] == delta6::proto::kWrenchRaw)) {
      board::markRecordQueued();
    }
  }
  void eepromRead(uint16_t address, uint8_t* data, uint16_t n) override {
    board::eepromRead(address, data, n);
  }
  void eepromWrite(uint16_t address, const uint8_t* data, uint16_t n) override {
    board::eepromWrite(address, data, n);
  }
  uint32_t micros() override { return board::micros(); }
  void sampleRateChanged(uint16_t rate_hz) override {
#if DELTA6_CALIBRATED
    delta6::calibration_set_period(delta6::calibration::kCalibrationConstants,
                                   1.0f / static_cast<float>(rate_hz), calibration_state);
#endif
#if DELTA6_RESIDUAL
    delta6::residual::configure(m::kModel, residual_state, rate_hz);
#endif
    board::startSampling(rate_hz);
    board::watchdogStart(rate_hz);
  }
};

BoardHardware hardware;
// In flash, like the defaults (the serial number, known at run time, goes to the device).
const delta6::Identity identity DELTA6_FLASH = {
    d::kName,
    d::kHash,
    {d::kFullScale[0], d::kFullScale[1], d::kFullScale[2], d::kFullScale[3], d::kFullScale[4],
     d::kFullScale[5]},
    d::kJointLimitRad,
    d::kJointLimitCounts,
    {delta6::kFirmwareVersionMajor, delta6::kFirmwareVersionMinor, delta6::kFirmwareVersionPatch},
    board::kBaud,
    DELTA6_MAX_RATE_HZ,
    0,   // serial number: given to the device in setup()
    kEepromAddress,
#if DELTA6_CALIBRATED
    delta6::calibration::kName,
    delta6::calibration::kHash,
#else
    nullptr,   // no calibration: the analytical model
    0,
#endif
#if DELTA6_RESIDUAL
    m::kName,
    m::kHash,
#else
    nullptr,   // no on-chip residual model
    0,
#endif
    DELTA6_MAX_RATE_PIPELINE_HZ,
};
// Zero counts 0 until the assembly is calibrated (ZERO_HERE, then SAVE_CONFIG).
// No filter, the identity tool frame, no overload limits.
const delta6::Config defaults DELTA6_FLASH = {
    DELTA6_DEFAULT_RATE_HZ, delta6::proto::kModeWrench, false, {0, 0, 0, 0, 0, 0},
    {0, 0, 0, 0, 0, 0}, 0.0f, {0, 0, 0}, {0, 0, 0}, {0, 0, 0, 0, 0, 0}};
delta6::Device device(hardware, identity, defaults);

bool workPending() { return queue_tail != queue_head || board::rxAvailable(); }

#if DELTA6_CALIBRATED
// The calibrated solver reads the fine table only (each joint has its calibrated table): the
// design's constants without the analytical solver's joint and branch tables, so that the
// linker drops those (1 KB of flash the calibrated image with a residual model needs).
constexpr delta6::SolverConstants calibratedSolver() {
  delta6::SolverConstants c = d::kSolverConstants;
  c.branch_table = nullptr;
  c.joint_table = nullptr;
  return c;
}
constexpr delta6::SolverConstants kCalibratedSolver = calibratedSolver();
#endif

// Check the frames, solve, and hand the sample to the device.
void process(const Latched& latched) {
  delta6::Sample s;
  s.time_us = latched.time_us;
  s.encoder_errors = 0;
  for (uint8_t j = 0; j < 6; ++j) {
    s.counts[j] = 0;   // a failed read sends 0, flagged: never a made-up angle
    if (delta6::encoder::decodeFrame(latched.word[j], latched.inverse[j], &s.counts[j])) {
      s.encoder_errors |= static_cast<uint8_t>(1u << j);
    }
  }
  board::mark(D6_MARK_SOLVE_START);
  if (s.encoder_errors == 0) {
    const uint16_t* zero = device.zeroCounts();
    int16_t delta[6];
    for (uint8_t j = 0; j < 6; ++j) delta[j] = delta6::wrap_count_delta(s.counts[j], zero[j]);
#if DELTA6_CALIBRATED || DELTA6_RESIDUAL
    const bool zero_changed = zeroChanged(zero);
#endif
#if DELTA6_CALIBRATED
    if (zero_changed) delta6::calibration_reset(calibration_state);
    if (latched.missed) delta6::calibration_gap(calibration_state);
    s.solver_ok = delta6::solve_calibrated(kCalibratedSolver,
                                           delta6::calibration::kCalibrationConstants,
                                           calibration_state, delta, s.wrench) == delta6::kSolveOk;
#else
    s.solver_ok = delta6::solve_counts(d::kSolverConstants, delta, s.wrench) == delta6::kSolveOk;
#endif
#if DELTA6_RESIDUAL
    applyResidual(s.solver_ok, zero_changed, delta, s.wrench);
#endif
  } else {
    s.solver_ok = false;   // no wrench without all six angles
    for (uint8_t i = 0; i < 6; ++i) s.wrench[i] = 0.0f;
#if DELTA6_CALIBRATED
    delta6::calibration_gap(calibration_state);   // the next sample's step is no speed
#endif
#if DELTA6_RESIDUAL
    delta6::residual::reset(residual_state);
#endif
  }
  board::mark(D6_MARK_SOLVE_END);
  s.overrun = latched.missed != 0;
  const uint32_t age = board::micros() - latched.time_us;
  s.loop_time_us = static_cast<uint16_t>(age > 0xFFFF ? 0xFFFF : age);
  s.temperature_centi = delta6::proto::kTemperatureUnknown;
  device.onSample(s);
}

}  // namespace

namespace app {

void onSampleTick() {
  if (latching) return;   // cannot happen below 10 kHz; a nested tick would corrupt the slot
  const uint8_t head = queue_head;
  const uint8_t next = static_cast<uint8_t>((head + 1) & (kQueueLength - 1));
  if (next == queue_tail) {
    if (missed != 0xFF) missed = static_cast<uint8_t>(missed + 1);
    board::mark(D6_MARK_TICK_MISSED);
    return;
  }
  latching = true;
  Latched& slot = queue[head];
  board::mark(D6_MARK_SCAN_START);
  slot.time_us = board::micros();
  board::scanEncoders(slot.word, slot.inverse);
  board::mark(D6_MARK_SCAN_END);
  slot.missed = missed;
  missed = 0;
  queue_head = next;
  latching = false;
}

void setup() {
  board::mark(D6_MARK_BOOT);
  board::init();
  device.setSerialNumber(board::serialNumber());
  // Loads the configuration, starts the sample timer.
  device.begin(board::resetCause(), board::bootId());
  board::mark(D6_MARK_READY);
}

void loop() {
#if defined(DELTA6_TEST_HOOKS)
  while (board::testHangRequested()) {
  }
#endif
  // Samples first, but received bytes get a turn after every sample: an overloaded loop
  // (a rate beyond what the board sustains) still hears STOP.
  bool worked = false;
  const uint8_t tail = queue_tail;
  if (tail != queue_head) {
    board::mark(D6_MARK_PROCESS_START);
    process(queue[tail]);
    queue_tail = static_cast<uint8_t>((tail + 1) & (kQueueLength - 1));
    board::mark(D6_MARK_PROCESS_END);
    board::watchdogKick();
    worked = true;
  }
  for (uint8_t i = 0; i < kBytesPerTurn; ++i) {
    const int16_t b = board::rxRead();
    if (b < 0) break;
    board::mark(D6_MARK_BYTE_START);
    device.onByte(static_cast<uint8_t>(b));
    board::mark(D6_MARK_BYTE_END);
    worked = true;
  }
  if (worked) return;
  device.service();
  board::idle(workPending);
}

}  // namespace app
