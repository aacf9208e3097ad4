$A << EOD
14.638 0.0625 31.6345 0.0625 0.0625 0.0625 0.0625 "D cframe 250it"
27.372 0.0521 31.5865 0.0625 0.0625 0.0417 0.0417 "D cframe 500it"
61.032 0.0 31.1281 0.0 0.0 0.0 0.0 "D cframe 1000it"
15.729 0.0677 32.6254 0.0625 0.0833 0.0625 0.0625 "- cframe 250it"
31.327 0.0573 32.3104 0.0625 0.0625 0.0417 0.0625 "- cframe 500it"
54.38 0.0469 32.3991 0.0417 0.0625 0.0417 0.0417 "- cframe 1000it"
EOD
$FB << EOD
14.638 0.0625 31.6345 0.0625 0.0625 0.0625 0.0625
27.372 0.0521 31.5865 0.0625 0.0625 0.0417 0.0417
54.38 0.0469 32.3991 0.0417 0.0625 0.0417 0.0417
61.032 0.0 31.1281 0.0 0.0 0.0 0.0
EOD
$FP << EOD
14.638 0.0625 31.6345 0.0625 0.0625 0.0625 0.0625
15.729 0.0677 32.6254 0.0625 0.0833 0.0625 0.0625
EOD
set terminal pngcairo size 1000,900 font ",10" noenhanced
set output "results/accuracy_vs_time/embedding_feature_decoder/embedding.png"
set multiplot layout 2,1 title "WATER-GS embedding on demo_scene (1/2 res): BER and PSNR against wall time"
set grid
set xlabel "embedding wall time (s, whole embed command; threads as in commands.txt)"
set ylabel "BER (fraction of bits wrong)"
set key outside right
set yrange [0:0.55]
plot $A using 1:4 with points pt 1 ps 1.2 title "identity", \
  $A using 1:5 with points pt 2 ps 1.2 title "gn:0.01", \
  $A using 1:6 with points pt 4 ps 1.2 title "dropout:0.1", \
  $A using 1:7 with points pt 8 ps 1.2 title "crop:0.1", \
  $A using 1:2 with points pt 7 ps 1.3 lc rgb "black" title "mean of the four", \
  $FB using 1:2 with linespoints pt 6 ps 2.4 lw 2 lc rgb "red" title "Pareto front (mean BER)", \
  0.5 with lines dt 2 lc rgb "gray" title "chance"
set ylabel "PSNR vs raw renders (dB)"
set title "points: D = distortion layers on, - = off; c = crop side (frame = whole views); it = iterations" font ",9"
set yrange [*:*]
plot $A using 1:3 with points pt 7 ps 1.3 lc rgb "black" title "points", \
  $A using 1:3:8 with labels offset 0,0.8 font ",8" notitle, \
  $FP using 1:3 with linespoints pt 6 ps 2.4 lw 2 lc rgb "blue" title "Pareto front (PSNR)"
unset multiplot
