/* pid_controller.c: a discrete PID per bridge with anti-windup.
 *
 *     u[k] = Kp * ( e[k] + tauD*(e[k] - e[k-1])/T + (T/tauI)*sum(e) )
 *
 * with sum(e), the running sum of the errors, clamped to +-windup_limit, and u clamped to +-100 %
 * duty. The thesis's parameter order: pid_set_parameters(bridge, kp, kd, ki, windup_limit) where
 * kd is tauD (s) and ki is tauI (s); ki = 0 disables the integral. The thesis does not state which
 * quantity its windup limit bounds; bounding sum(e) is our reading (as in the Python port). */
#include "pid_controller.h"

Pid pids[2] = {
    {.period = 0.005f, .first = true},
    {.period = 0.005f, .first = true},
};

void pid_set_parameters(int bridge, float kp, float kd, float ki, float windup_limit)
{
    Pid *p = &pids[bridge];
    p->kp = kp;
    p->kd = kd;
    p->ki = ki;
    p->windup_limit = windup_limit;
}

void pid_set_point(int bridge, float set_point)
{
    pids[bridge].set_point = set_point;
}

void pid_set_period(int bridge, float period)
{
    pids[bridge].period = period;
}

void pid_reset(int bridge)
{
    Pid *p = &pids[bridge];
    p->prev_error = 0.0f;
    p->error_sum = 0.0f;
    p->first = true;
}

/* One controller step; the output in percent duty, clamped to +-100. */
float pid_apply(int bridge, float measured)
{
    Pid *p = &pids[bridge];
    float error = p->set_point - measured;
    if (p->first) {                        /* no derivative kick on the first sample after a reset */
        p->prev_error = error;
        p->first = false;
    }
    p->error_sum += error;
    if (p->error_sum > p->windup_limit)
        p->error_sum = p->windup_limit;
    else if (p->error_sum < -p->windup_limit)
        p->error_sum = -p->windup_limit;
    float derivative = p->kd * (error - p->prev_error) / p->period;
    float integral = p->ki != 0.0f ? (p->period / p->ki) * p->error_sum : 0.0f;
    p->prev_error = error;
    float u = p->kp * (error + derivative + integral);
    if (u > OUTPUT_LIMIT)
        return OUTPUT_LIMIT;
    if (u < -OUTPUT_LIMIT)
        return -OUTPUT_LIMIT;
    return u;
}
