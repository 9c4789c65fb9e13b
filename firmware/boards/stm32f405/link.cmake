# STM32F405 link firmware images and their chip drivers (included from firmware/link/CMakeLists.txt
# in the cross build, once ps_link exists).
#   playscope-link-fw     table slots in RAM: runs under QEMU (no flash controller there)
#   playscope-link-fw-hw  table slots in flash sectors 10/11 via the FLASH registers: compiled only
#   playscope-link-fw-usb the link on USB (OTG FS port of the portable USB core), flash slots:
#                         compiled only (QEMU does not emulate the OTG peripheral)
set(PS_STM32F405_DIR ${PS_ROOT}/firmware/boards/stm32f405)
add_library(ps_storage_stm32f4 STATIC ${PS_STM32F405_DIR}/pss_flash_stm32f4.c)
target_include_directories(ps_storage_stm32f4 PUBLIC ${PS_STM32F405_DIR})
target_link_libraries(ps_storage_stm32f4 PUBLIC ps_storage)

foreach(variant IN ITEMS ram hw)
  if(variant STREQUAL "ram")
    set(t playscope-link-fw)
  else()
    set(t playscope-link-fw-hw)
  endif()
  add_executable(${t} ${PS_STM32F405_DIR}/link_main.c)
  target_link_libraries(${t} PRIVATE ps_link ps_board_stm32f405)
  if(variant STREQUAL "hw")
    target_compile_definitions(${t} PRIVATE PSL_FLASH_HW=1)
    target_link_libraries(${t} PRIVATE ps_storage_stm32f4)
  endif()
  set_target_properties(${t} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/link-fw)
  ps_firmware_image(${t})
endforeach()

add_library(ps_usb_stm32f4 STATIC ${PS_STM32F405_DIR}/dcd_otgfs.c)
target_include_directories(ps_usb_stm32f4 PRIVATE ${PS_STM32F405_DIR})
target_link_libraries(ps_usb_stm32f4 PUBLIC ps_usb_core)
add_executable(playscope-link-fw-usb ${PS_STM32F405_DIR}/link_usb_main.c)
target_link_libraries(playscope-link-fw-usb PRIVATE ps_link ps_usb_stm32f4 ps_storage_stm32f4 ps_board_stm32f405)
set_target_properties(playscope-link-fw-usb PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/link-fw)
ps_firmware_image(playscope-link-fw-usb)
