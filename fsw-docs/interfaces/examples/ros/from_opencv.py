# The ROS camera_info pair of ../calib-opencv.json, rectified by OpenCV's
# cv2.stereoRectify (default flags and alpha), as ROS camera_calibration stores it.
# Run from fsw-docs/interfaces/examples: python3 ros/from_opencv.py
import json, numpy as np, cv2
c=json.load(open('calib-opencv.json'))
K1=np.array(c['left']['K']);D1=np.array(c['left']['dist']);K2=np.array(c['right']['K']);D2=np.array(c['right']['dist'])
R=np.array(c['R']);T=np.array(c['T']).reshape(3,1)
W,H=c['image_size']
R1,R2,P1,P2,Q,_,_=cv2.stereoRectify(K1,D1,K2,D2,(W,H),R,T)
def fmt(v): return repr(float(v))
def mat(key,M):
    M=np.atleast_2d(np.asarray(M,dtype=float)); r,cc=M.shape
    return f"{key}:\n  rows: {r}\n  cols: {cc}\n  data: [{', '.join(fmt(x) for x in M.flatten())}]\n"
for name,K,D,Rr,P in (('left',K1,D1,R1,P1),('right',K2,D2,R2,P2)):
    s=f"image_width: {W}\nimage_height: {H}\ncamera_name: {name}\n"+mat('camera_matrix',K)+"distortion_model: plumb_bob\n"+mat('distortion_coefficients',D)+mat('rectification_matrix',Rr)+mat('projection_matrix',P)
    open(f'ros/{name}.yaml','w').write(s)
open('ros/calib.json','w').write('{"ros_camera_info": {"left": "left.yaml", "right": "right.yaml"}}\n')
print(cv2.__version__)
