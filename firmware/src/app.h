// The Delta6 firmware application: a fixed-rate sampling loop around the portable core.
//
//   timer interrupt, every period: latch the six encoders (one parallel scan) into a small
//       queue; if the queue is full the period is lost and the next sample says so (overrun)
//   main loop: take the oldest latched sample, check the frames, solve, hand it to
//       delta6::Device (status, tare, quantisation, the record into the UART queue); with no
//       sample waiting, feed one received byte to the device; with nothing to do, sleep
//
// The UART sends from its own interrupt, so a record goes out while the next sample is being
// solved. docs/firmware.md ("The application") has the timing.
#ifndef DELTA6_APP_H
#define DELTA6_APP_H

#include <stdint.h>

namespace app {

void setup();
void loop();
// Called by the board's sample timer interrupt, once per period, interrupts enabled.
void onSampleTick();

}  // namespace app

#endif  // DELTA6_APP_H
