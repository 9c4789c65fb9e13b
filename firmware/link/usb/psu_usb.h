/* USB 2.0 chapter 9 wire structures and constants used by the playscope device (packed, sizes pinned). */
#ifndef PSU_USB_H
#define PSU_USB_H

#include <stdint.h>
#include "ps_defs.h"

/* All multi-byte fields are little-endian on the wire; both targets (Cortex-M4, x86-64)
 * are little-endian, so the structs below are the wire bytes as they are. */

enum {
    PSU_DESC_DEVICE = 1,
    PSU_DESC_CONFIGURATION = 2,
    PSU_DESC_STRING = 3,
    PSU_DESC_INTERFACE = 4,
    PSU_DESC_ENDPOINT = 5,
    PSU_DESC_DEVICE_QUALIFIER = 6,  /* high-speed capable devices only: we stall it (full speed) */
};

enum {
    PSU_REQ_GET_STATUS = 0,
    PSU_REQ_CLEAR_FEATURE = 1,
    PSU_REQ_SET_FEATURE = 3,
    PSU_REQ_SET_ADDRESS = 5,
    PSU_REQ_GET_DESCRIPTOR = 6,
    PSU_REQ_SET_DESCRIPTOR = 7,
    PSU_REQ_GET_CONFIGURATION = 8,
    PSU_REQ_SET_CONFIGURATION = 9,
    PSU_REQ_GET_INTERFACE = 10,
    PSU_REQ_SET_INTERFACE = 11,
};

/* bmRequestType fields */
enum {
    PSU_RT_DIR_IN = 0x80,
    PSU_RT_TYPE_MASK = 0x60,
    PSU_RT_TYPE_STANDARD = 0x00,
    PSU_RT_RECIP_MASK = 0x1F,
    PSU_RT_RECIP_DEVICE = 0,
    PSU_RT_RECIP_INTERFACE = 1,
    PSU_RT_RECIP_ENDPOINT = 2,
};

enum {
    PSU_FEATURE_ENDPOINT_HALT = 0,
    PSU_FEATURE_DEVICE_REMOTE_WAKEUP = 1,
};

enum {
    PSU_EP_TYPE_CONTROL = 0,
    PSU_EP_TYPE_BULK = 2,
    PSU_EP_DIR_IN = 0x80,
};

typedef struct PS_PACKED psu_setup {
    uint8_t bmRequestType;
    uint8_t bRequest;
    uint16_t wValue;
    uint16_t wIndex;
    uint16_t wLength;
} psu_setup_t;
PS_STATIC_ASSERT(sizeof(psu_setup_t) == 8, "setup packet is 8 bytes");

typedef struct PS_PACKED psu_device_desc {
    uint8_t bLength;
    uint8_t bDescriptorType;
    uint16_t bcdUSB;
    uint8_t bDeviceClass;
    uint8_t bDeviceSubClass;
    uint8_t bDeviceProtocol;
    uint8_t bMaxPacketSize0;
    uint16_t idVendor;
    uint16_t idProduct;
    uint16_t bcdDevice;
    uint8_t iManufacturer;
    uint8_t iProduct;
    uint8_t iSerialNumber;
    uint8_t bNumConfigurations;
} psu_device_desc_t;
PS_STATIC_ASSERT(sizeof(psu_device_desc_t) == 18, "device descriptor is 18 bytes");

typedef struct PS_PACKED psu_config_desc {
    uint8_t bLength;
    uint8_t bDescriptorType;
    uint16_t wTotalLength;
    uint8_t bNumInterfaces;
    uint8_t bConfigurationValue;
    uint8_t iConfiguration;
    uint8_t bmAttributes;
    uint8_t bMaxPower;           /* units of 2 mA */
} psu_config_desc_t;
PS_STATIC_ASSERT(sizeof(psu_config_desc_t) == 9, "configuration descriptor is 9 bytes");

typedef struct PS_PACKED psu_iface_desc {
    uint8_t bLength;
    uint8_t bDescriptorType;
    uint8_t bInterfaceNumber;
    uint8_t bAlternateSetting;
    uint8_t bNumEndpoints;
    uint8_t bInterfaceClass;
    uint8_t bInterfaceSubClass;
    uint8_t bInterfaceProtocol;
    uint8_t iInterface;
} psu_iface_desc_t;
PS_STATIC_ASSERT(sizeof(psu_iface_desc_t) == 9, "interface descriptor is 9 bytes");

typedef struct PS_PACKED psu_ep_desc {
    uint8_t bLength;
    uint8_t bDescriptorType;
    uint8_t bEndpointAddress;
    uint8_t bmAttributes;
    uint16_t wMaxPacketSize;
    uint8_t bInterval;
} psu_ep_desc_t;
PS_STATIC_ASSERT(sizeof(psu_ep_desc_t) == 7, "endpoint descriptor is 7 bytes");

#endif /* PSU_USB_H */
