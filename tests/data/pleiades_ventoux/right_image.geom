adjustment_0.adj_param_0.center:  0
adjustment_0.adj_param_0.description:  intrack_offset
adjustment_0.adj_param_0.lock_flag:  0
adjustment_0.adj_param_0.parameter:  0
adjustment_0.adj_param_0.sigma:  50
adjustment_0.adj_param_0.units:  pixel
adjustment_0.adj_param_1.center:  0
adjustment_0.adj_param_1.description:  crtrack_offset
adjustment_0.adj_param_1.lock_flag:  0
adjustment_0.adj_param_1.parameter:  0
adjustment_0.adj_param_1.sigma:  50
adjustment_0.adj_param_1.units:  pixel
adjustment_0.adj_param_2.center:  0
adjustment_0.adj_param_2.description:  intrack_scale
adjustment_0.adj_param_2.lock_flag:  0
adjustment_0.adj_param_2.parameter:  0
adjustment_0.adj_param_2.sigma:  50
adjustment_0.adj_param_2.units:  unknown
adjustment_0.adj_param_3.center:  0
adjustment_0.adj_param_3.description:  crtrack_scale
adjustment_0.adj_param_3.lock_flag:  0
adjustment_0.adj_param_3.parameter:  0
adjustment_0.adj_param_3.sigma:  50
adjustment_0.adj_param_3.units:  unknown
adjustment_0.adj_param_4.center:  0
adjustment_0.adj_param_4.description:  map_rotation
adjustment_0.adj_param_4.lock_flag:  0
adjustment_0.adj_param_4.parameter:  0
adjustment_0.adj_param_4.sigma:  0.1
adjustment_0.adj_param_4.units:  degrees
adjustment_0.description:  Initial adjustment
adjustment_0.dirty_flag:  0
adjustment_0.number_of_params:  5
bias_error:  0
ce90_absolute:  0
ce90_relative:  0
current_adjustment:  0
height_off:  1075
height_scale:  885
image_id:  690908101-002
lat_off:  44.1372884414224
lat_scale:  0.100768307399168
line_den_coeff_00:  1
line_den_coeff_01:  0.00103074334218907
line_den_coeff_02:  -0.000722635694465235
line_den_coeff_03:  -3.9223699310353e-05
line_den_coeff_04:  -1.4851351508508e-05
line_den_coeff_05:  -2.06975751018941e-07
line_den_coeff_06:  6.21998277403711e-07
line_den_coeff_07:  -5.41240169518995e-06
line_den_coeff_08:  1.77573019002297e-05
line_den_coeff_09:  -7.49184163287626e-06
line_den_coeff_10:  9.71215814220465e-09
line_den_coeff_11:  -4.15696150651912e-08
line_den_coeff_12:  2.39649007387542e-07
line_den_coeff_13:  -1.45199012692277e-08
line_den_coeff_14:  1.94457780766438e-07
line_den_coeff_15:  -1.84811046118882e-07
line_den_coeff_16:  -3.86760505122431e-09
line_den_coeff_17:  1.25971035047874e-09
line_den_coeff_18:  -4.47403538246287e-08
line_den_coeff_19:  4.43642443542998e-10
line_num_coeff_00:  -0.00170866582987503
line_num_coeff_01:  0.0250913355215367
line_num_coeff_02:  -1.04049790937513
line_num_coeff_03:  -0.0161990924944425
line_num_coeff_04:  0.00093397983580219
line_num_coeff_05:  1.61025172609734e-05
line_num_coeff_06:  -1.07514610294424e-05
line_num_coeff_07:  -0.000631797410736778
line_num_coeff_08:  0.00103680990926496
line_num_coeff_09:  1.8887414103972e-06
line_num_coeff_10:  -4.85634911419117e-07
line_num_coeff_11:  4.72207480421131e-07
line_num_coeff_12:  -2.30449838290949e-05
line_num_coeff_13:  -1.91966248014777e-07
line_num_coeff_14:  5.82630355610413e-06
line_num_coeff_15:  2.53210935145836e-05
line_num_coeff_16:  7.77558415557828e-06
line_num_coeff_17:  4.71928474149212e-08
line_num_coeff_18:  -6.90185222354529e-08
line_num_coeff_19:  1.19949846381443e-07
line_off:  20417.5
line_scale:  21001.5
ll_lat:  44.0408253825549
ll_lon:  5.16512965058162
long_off:  5.28510551079709
long_scale:  0.129903687611518
lr_lat:  44.0450962046497
lr_lon:  5.41292493804875
meters_per_pixel_x:  0.510321084807497
meters_per_pixel_y:  0.512315816473669
number_lines:  40845
number_of_adjustments:  1
number_samples:  38987
polynomial_format:  B
rand_error:  0
rect:  0 0 38986 40844
ref_point_hgt:  1075
ref_point_lat:  44.1371367164139
ref_point_line:  20422
ref_point_lon:  5.28707315305628
ref_point_samp:  19493
samp_den_coeff_00:  1
samp_den_coeff_01:  0.000434277914115595
samp_den_coeff_02:  0.000769823670686679
samp_den_coeff_03:  -0.000715285189284844
samp_den_coeff_04:  -2.74473763019865e-05
samp_den_coeff_05:  -2.76194834705389e-07
samp_den_coeff_06:  -1.1856649475247e-07
samp_den_coeff_07:  2.16694397174453e-06
samp_den_coeff_08:  7.80040807878226e-06
samp_den_coeff_09:  -5.23768137810548e-06
samp_den_coeff_10:  -1.03976979911733e-07
samp_den_coeff_11:  -5.41926800207841e-08
samp_den_coeff_12:  -2.42341338043804e-07
samp_den_coeff_13:  -3.68108121837406e-09
samp_den_coeff_14:  1.64514804815834e-07
samp_den_coeff_15:  -4.50939075045594e-08
samp_den_coeff_16:  -8.04842849478713e-09
samp_den_coeff_17:  2.6421335422591e-08
samp_den_coeff_18:  4.20099090134809e-08
samp_den_coeff_19:  6.12274816607025e-09
samp_num_coeff_00:  -2.73484358298427e-05
samp_num_coeff_01:  1.02022209121473
samp_num_coeff_02:  0.0169364094018337
samp_num_coeff_03:  0.00457238343925625
samp_num_coeff_04:  -0.000776509567873981
samp_num_coeff_05:  0.000706795109550647
samp_num_coeff_06:  -0.000334457716130411
samp_num_coeff_07:  -0.000388457430070953
samp_num_coeff_08:  0.00144233614099151
samp_num_coeff_09:  -3.31706152124915e-06
samp_num_coeff_10:  1.01008280984232e-06
samp_num_coeff_11:  -1.20424574636143e-05
samp_num_coeff_12:  -1.23494098589761e-05
samp_num_coeff_13:  -4.53823502376133e-06
samp_num_coeff_14:  3.83304043193136e-05
samp_num_coeff_15:  -3.64496349748621e-05
samp_num_coeff_16:  -3.71585759115245e-07
samp_num_coeff_17:  -6.32402487016171e-07
samp_num_coeff_18:  -2.71248643242839e-06
samp_num_coeff_19:  -2.37957158601208e-08
samp_off:  19185.5
samp_scale:  19999.5
sensor:  PHR 1B
support_data.across_track_incidence_angle:  """-2.80236454319563 -3.01540170126559 -3.2253217066235 """
support_data.along_track_incidence_angle:  """11.2187717727984 11.1775009484151 11.1382238683275 """
support_data.azimuth_angle:  """149.028187199239 148.948734090296 148.868328730083 """
support_data.band_name_list:  """P """
support_data.elevation_angle:  """59.753142925513 59.8345770256926 59.9157943825498 """
support_data.image_date:  2013-08-05T10:42:52.3Z
support_data.image_id:  690908101-002
support_data.image_size:  38987 40845
support_data.incident_angle:  """11.5464475149547 11.5575420670543 11.5736257937341 """
support_data.instrument:  PHR
support_data.instrument_index:  1B
support_data.line_period:  0.0735
support_data.ll_ground_point:  44.0422169464329 5.16549605187508 0 WGE
support_data.lr_ground_point:  44.0451081663806 5.41293072521553 0 WGE
support_data.number_bands:  1
support_data.number_of_across_track_incidence_angle:  3
support_data.number_of_along_track_incidence_angle:  3
support_data.number_of_azimuth_angle:  3
support_data.number_of_elevation_angle:  3
support_data.number_of_incident_angle:  3
support_data.number_of_scene_orientation:  3
support_data.number_of_viewing_angle:  3
support_data.physical_bias:  """0 """
support_data.physical_gain:  """12.04 """
support_data.processing_level:  SENSOR
support_data.production_date:  2013-10-21T15:50:46.740
support_data.reference_ground_point:  44.1378040533582 5.28717840031257 0 WGE
support_data.reference_image_point:  19493.5 20422.5
support_data.scene_orientation:  """178.964493373485 179.121322915205 179.284495037436 """
support_data.sensorID:  PHR 1B
support_data.solar_irradiance:  """1548 """
support_data.swath_first_col:  815
support_data.swath_last_col:  39801
support_data.time_range_end:  2013-08-05T10:42:55.3939580Z
support_data.time_range_start:  2013-08-05T10:42:52.3919240Z
support_data.type:  ossimPleiadesDimapSupportData
support_data.ul_ground_point:  44.2301087671666 5.16104905062133 0 WGE
support_data.ur_ground_point:  44.2337823334525 5.40923777353834 0 WGE
support_data.viewing_angle:  """10.2167435962884 10.2276186571087 10.2430376767591 """
type:  ossimPleiadesModel
ul_lat:  44.2287476818978
ul_lon:  5.16077488919569
ur_lat:  44.2337425977704
ur_lon:  5.40922288906057
