// techmap for the cells `memory_libmap -lib sdp_rams.txt` makes: each
// becomes one instance of a black-box macro (sdp_rams_macros.v). Put your
// SRAM compiler's or vendor's RAM behind those module names (or edit the
// instances below to call it directly).

module $__HIERMERGE_SDP_1024X32_ (...);
    input CLK_C;
    input PORT_W_CLK;
    input [9:0] PORT_W_ADDR;
    input [31:0] PORT_W_WR_DATA;
    input PORT_W_WR_EN;
    input PORT_R_CLK;
    input [9:0] PORT_R_ADDR;
    input PORT_R_RD_EN;
    output [31:0] PORT_R_RD_DATA;

    hiermerge_sdp_ram_1024x32 _TECHMAP_REPLACE_ (
        .clk(CLK_C),
        .we(PORT_W_WR_EN),
        .waddr(PORT_W_ADDR),
        .wdata(PORT_W_WR_DATA),
        .re(PORT_R_RD_EN),
        .raddr(PORT_R_ADDR),
        .rdata(PORT_R_RD_DATA)
    );
endmodule

module $__HIERMERGE_SDP_256X32_ (...);
    input CLK_C;
    input PORT_W_CLK;
    input [7:0] PORT_W_ADDR;
    input [31:0] PORT_W_WR_DATA;
    input PORT_W_WR_EN;
    input PORT_R_CLK;
    input [7:0] PORT_R_ADDR;
    input PORT_R_RD_EN;
    output [31:0] PORT_R_RD_DATA;

    hiermerge_sdp_ram_256x32 _TECHMAP_REPLACE_ (
        .clk(CLK_C),
        .we(PORT_W_WR_EN),
        .waddr(PORT_W_ADDR),
        .wdata(PORT_W_WR_DATA),
        .re(PORT_R_RD_EN),
        .raddr(PORT_R_ADDR),
        .rdata(PORT_R_RD_DATA)
    );
endmodule
