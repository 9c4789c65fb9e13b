/* Shared compiler glue for common/ headers: packing and static size checks. */
#ifndef PS_DEFS_H
#define PS_DEFS_H

/* PS_CDEF is defined when the host preprocesses these headers for cffi's cdef(),
 * which understands neither attributes nor _Static_assert; the host then declares
 * the structs with packed=True so the layout stays identical. */
#ifdef PS_CDEF
#define PS_PACKED
#define PS_STATIC_ASSERT(cond, msg)
#else
#define PS_PACKED __attribute__((packed))
#define PS_STATIC_ASSERT(cond, msg) _Static_assert(cond, msg)
#endif

#endif /* PS_DEFS_H */
