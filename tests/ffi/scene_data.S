/* The CI flight-path scene's bytes, linked into the harness as read-only
 * data: the map product (the store's memory-mapped flash) and the stereo
 * pair (the camera's frame memory). run.sh assembles this with
 * -Wa,-I<bundle dir>, the directory written by flight_bundle. On the M7 the
 * map goes to the PSRAM section .vtsm_flash (tests/ffi/m7/link.ld). */
    .section .vtsm_flash,"a"
    .balign 16
    .global scene_map
scene_map:
    .incbin "map.vmap"
    .global scene_map_end
scene_map_end:

    .section .rodata.vtsm_frames,"a"
    .balign 16
    .global scene_left
scene_left:
    .incbin "left.gray"
    .global scene_right
scene_right:
    .incbin "right.gray"
    .global scene_right_end
scene_right_end:

    .section .note.GNU-stack,"",%progbits
