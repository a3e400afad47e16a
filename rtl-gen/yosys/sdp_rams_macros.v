// The RAM macros hiermerge's synthesis maps its buffers onto (see
// sdp_rams.txt): simple dual-port, one write port and one registered read
// port on one rising clock. On a clock with `we`, `wdata` is stored at
// `waddr`; on a clock with `re`, `rdata` takes the word at `raddr` (the old
// word if the same clock writes it) and holds it otherwise. Black boxes
// here: an ASIC flow puts its SRAM compiler's macro in their place, an
// FPGA flow its block RAM primitive.

(* blackbox *)
module hiermerge_sdp_ram_1024x32 (
    input clk,
    input we,
    input [9:0] waddr,
    input [31:0] wdata,
    input re,
    input [9:0] raddr,
    output [31:0] rdata
);
endmodule

(* blackbox *)
module hiermerge_sdp_ram_256x32 (
    input clk,
    input we,
    input [7:0] waddr,
    input [31:0] wdata,
    input re,
    input [7:0] raddr,
    output [31:0] rdata
);
endmodule
