#ifndef PID_CONTROLLER_H
#define PID_CONTROLLER_H

#include <stdbool.h>

#define BRIDGE_A 0
#define BRIDGE_B 1
#define OUTPUT_LIMIT 100.0f     /* percent duty */

typedef struct {
    float kp;
    float kd;                   /* tauD, s */
    float ki;                   /* tauI, s (0: no integral action) */
    float windup_limit;
    float set_point;
    float period;               /* T, s */
    float prev_error;
    float error_sum;
    bool first;
} Pid;

extern Pid pids[2];

void pid_set_parameters(int bridge, float kp, float kd, float ki, float windup_limit);
void pid_set_point(int bridge, float set_point);
void pid_set_period(int bridge, float period);
void pid_reset(int bridge);
float pid_apply(int bridge, float measured);

#endif
