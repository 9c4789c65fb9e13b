/* Fixed-point formats shared by the firmware and the host: every quantity is Q16.16. */
#ifndef PS_FIXED_H
#define PS_FIXED_H

/* One format for every physical quantity on the wire, in tables and in the firmware:
 * signed Q16.16 in an int32_t, i.e. value = raw / 65536.
 *   q   actuator position   (mm of cable or deg of commanded angle, see pst_header_t.q_unit)
 *   c   configuration var.  (bending angle, deg)
 *   B   backlash width      (actuator units)
 *   u,v marker position     (px)
 * Range +-32768 units, resolution 1.5e-5 units. Names carry the format: q_q16, b_q16.
 * Times are uint32_t microseconds (t_us) and wrap every 71.6 min; differences are taken
 * modulo 2^32, so any two times closer than 35 min compare correctly. */
enum {
    PS_FRAC_BITS = 16,
    PS_Q16_ONE = 65536,
};

#endif /* PS_FIXED_H */
