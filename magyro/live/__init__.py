"""`magyro watch`: live excitation feedback while a recording is being made (issue 16, item 1).

    sources   where the lines come from (standard input, a serial port, a file still being
              written) and how a line `t,gx,gy,gz,mx,my,mz[,ax,ay,az]` becomes samples; bad lines are counted
    monitor   `ExcitationMonitor`: the integral of M^T M kept as the samples arrive (O(1) per
              sample), rank against the noise floor, field-direction coverage, the predicted std
              of `magyro observe` refreshed in the background, the accelerometer's poses and rank
              (`gravity.accelerometer_parameters`), and the data so far (`Status`)
    accelerometer  `AccelerometerPart`: with `ax ay az` in the stream, `magyro observe`'s accelerometer
              section (poses held, rank of its 12 parameters, poses to hold) on the data so far
    display   the terminal view (rich Live on stderr, or plain lines) and the `--status` JSON lines
    stream    `stream_session`: a session written as CSV lines in (accelerated) real time, for
              `magyro simulate PROBLEM --stream`

The command functions are in `magyro.cli.live`.
"""
