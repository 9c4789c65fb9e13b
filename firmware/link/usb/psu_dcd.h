/* Chip port of the USB device stack: the few operations psu_device.c needs from a device controller. */
#ifndef PSU_DCD_H
#define PSU_DCD_H

/* A port implements the functions below and reports bus events back by calling the
 * psu_dcd_event_* functions of psu_device.h (from its interrupt handler or a poll loop;
 * never re-entrantly). Endpoint addresses carry the direction in bit 7 (0x81 = IN 1).
 * Transfers are whole transfers, not packets: the port splits them into max-packet
 * sized packets and reports completion once, so the core never sees packet boundaries. */

#include <stdbool.h>
#include <stdint.h>

struct psu_dev;

/* Bring the controller up, device mode, full speed, and connect (pull-up on D+). dev is
 * handed back to the psu_dcd_event_* calls; one device per controller. */
void psu_dcd_init(struct psu_dev *dev);

/* Program the device address from SET_ADDRESS. Called when the SETUP arrives, before
 * the status stage; a controller that must apply it only after the status IN (most
 * non-Synopsys cores) defers it itself. The Synopsys OTG core wants it right away. */
void psu_dcd_set_address(uint8_t addr);

/* Configure and enable a non-control endpoint (type PSU_EP_TYPE_BULK, max packet in bytes). */
void psu_dcd_ep_open(uint8_t ep_addr, uint8_t type, uint16_t max_packet_bytes);

/* Disable an endpoint and drop any transfer on it (SET_CONFIGURATION 0, bus reset). */
void psu_dcd_ep_close(uint8_t ep_addr);

/* Start one transfer. IN: send len bytes from buf (len 0 = a zero-length packet). OUT:
 * receive up to len bytes into buf; it ends at a short packet or when len are in.
 * buf must stay valid until psu_dcd_event_xfer_done for this endpoint. Returns false
 * if a transfer is already running on the endpoint. Endpoint 0 is used for the data
 * and status stages of control transfers. */
bool psu_dcd_ep_xfer(uint8_t ep_addr, uint8_t *buf, uint16_t len);

/* Answer STALL on the endpoint until cleared (endpoint 0: until the next SETUP). */
void psu_dcd_ep_stall(uint8_t ep_addr);

/* Clear a stall and reset the data toggle to DATA0 (CLEAR_FEATURE ENDPOINT_HALT). */
void psu_dcd_ep_clear_stall(uint8_t ep_addr);

#endif /* PSU_DCD_H */
