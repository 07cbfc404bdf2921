// The checkerboard's radiance: square cells of side u_emitter_cell (mm) along u and v,
// white where the cell's row and column have the same parity, black elsewhere.
uniform real u_emitter_cell;   // mm

float emitter_radiance(real2 uv, int pattern) {
    real2 cell = floor(uv / u_emitter_cell);
    return (mod(cell.x + cell.y, 2.0) < 0.5) ? 1.0 : 0.0;
}
