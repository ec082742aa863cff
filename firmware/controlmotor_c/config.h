/* Build-time parameters: the same defaults as the Python port (mcusim.fw.controlmotor.app
 * DEFAULTS), each overridable with -DNAME=value. The thesis gives no figure for the periods and
 * gains; these are the port's choices (the gains are tuned on the simulator's motor model). */
#ifndef CONFIG_H
#define CONFIG_H

/* 1: the thesis's literal code with its two bugs (see README.md); 0: the corrected firmware */
#ifndef CONTROLMOTOR_THESIS
#define CONTROLMOTOR_THESIS 0
#endif

#define configTICK_RATE_HZ 1000U          /* the FreeRTOS tick of the thesis firmware */
#ifndef PID_PERIOD_MS
#define PID_PERIOD_MS 5U                  /* period of the two PID tasks */
#endif
#ifndef EXECUTOR_PERIOD_MS
#define EXECUTOR_PERIOD_MS 10U            /* micro-ROS executor spin */
#endif
#ifndef PID_KP
#define PID_KP 400.0f                     /* % duty per rad of output-shaft error */
#endif
#ifndef PID_KD
#define PID_KD 0.05f                      /* derivative time tauD, s */
#endif
#ifndef PID_KI
#define PID_KI 0.25f                      /* integral time tauI, s (0: no integral action) */
#endif
#ifndef PID_WINDUP_LIMIT
#define PID_WINDUP_LIMIT 2.0f             /* bound on the error sum, rad * samples */
#endif
#ifndef ENCODER_FILTER
#define ENCODER_FILTER 0U                 /* ICxF of the encoder timers */
#endif
#ifndef COUNTS_PER_TURN
#define COUNTS_PER_TURN 1920U             /* 64 CPR x 30:1, quadrature counts per output turn */
#endif

#endif
