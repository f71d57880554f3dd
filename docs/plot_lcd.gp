# Plots docs/bench_lcd.dat (bench_lcd --dat) to docs/lcd_rmse.png: relative RMSE of the LCD
# panel against one-core CPU seconds for each sampling strategy.
#   gnuplot docs/plot_lcd.gp      (from the repository root)
set terminal pngcairo size 900,540 font "sans,11"
set output "docs/lcd_rmse.png"
set logscale xy
set xlabel "one-core CPU seconds for the 400 x 300 panel (samples per texel x cost per sample)"
set ylabel "relative RMSE against 262144 spp"
set grid
set key top right
set title "LCD final gather: error against time"
plot "docs/bench_lcd.dat" index 0 using 2:3 with linespoints lw 2 title "BRDF sampling", \
     "docs/bench_lcd.dat" index 1 using 2:3 with linespoints lw 2 title "cosine sampling", \
     "docs/bench_lcd.dat" index 2 using 2:3 with linespoints lw 2 title "MIS BRDF + cosine", \
     "docs/bench_lcd.dat" index 3 using 2:3 with linespoints lw 2 title "MIS + window", \
     "docs/bench_lcd.dat" index 4 using 2:3 with linespoints lw 2 title "MIS + env light", \
     "docs/bench_lcd.dat" index 5 using 2:3 with linespoints lw 2 title "MIS + window + env light", \
     0.01 with lines lc rgb "black" dt 3 title "1%"
