use ecr_macros::ecr_method;

ecr_method!(r = 33);

fn main() {}
